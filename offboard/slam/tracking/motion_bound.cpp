#include "slam/tracking/motion_bound.hpp"

namespace rgbdquad::slam {

void MotionBound::add(double stamp_s, const Eigen::Vector3d& p_world_m) {
  if (!history_.empty() && !(stamp_s > history_.back().stamp_s)) history_.clear();
  history_.push_back(Sample{stamp_s, p_world_m});
  while (history_.size() > options_.capacity) history_.pop_front();
}

MotionBoundCheck MotionBound::check(double stamp_s, const Eigen::Vector3d& p_world_m) const {
  MotionBoundCheck out;
  if (history_.size() < 2) return out;
  const Sample& last = history_.back();
  // The newest sample at least baseline_s before the last one, else the oldest kept.
  const Sample* first = &history_.front();
  for (auto it = history_.rbegin() + 1; it != history_.rend(); ++it)
    if (last.stamp_s - it->stamp_s >= options_.baseline_s) {
      first = &*it;
      break;
    }
  const double baseline = last.stamp_s - first->stamp_s;
  const double dt = stamp_s - last.stamp_s;
  if (!(baseline > 0) || dt < 0) return out;
  const Eigen::Vector3d v = (last.p_world_m - first->p_world_m) / baseline;
  out.checked = true;
  out.deviation_m = (p_world_m - (last.p_world_m + v * dt)).norm();
  out.bound_m = options_.margin_m + 0.5 * options_.max_acceleration_m_per_s2 * dt * (dt + baseline);
  return out;
}

}  // namespace rgbdquad::slam
