// LLC clamp and GLC candidate rotation; see loop.hpp.
#include "slam/thesis/loop.hpp"

#include <algorithm>
#include <cmath>

namespace rgbdquad::slam {

bool LoopOptions::is_valid(std::string* error) const {
  if (!(llc_max_fraction >= 0 && llc_max_fraction <= 1) || glc_blocks < 1 ||
      glc_exclude_latest < 0 || !(glc_min_match_fraction >= 0 && glc_min_match_fraction <= 1) ||
      !(glc_min_inlier_fraction >= 0 && glc_min_inlier_fraction <= 1)) {
    if (error) *error = "loop: options out of range";
    return false;
  }
  return true;
}

Eigen::Isometry3d clamp_llc_correction(const Eigen::Isometry3d& T_pred,
                                       const Eigen::Isometry3d& T_meas,
                                       const Eigen::Isometry3d& T_edge, double max_fraction) {
  if (!T_pred.matrix().allFinite() || !T_meas.matrix().allFinite() ||
      !T_edge.matrix().allFinite() || !(max_fraction >= 0))
    return T_pred;
  // Correction expressed in the world frame: T_meas = D * T_pred.
  const Eigen::Vector3d dt = T_meas.translation() - T_pred.translation();
  const Eigen::Quaterniond q_pred(T_pred.rotation()), q_meas(T_meas.rotation());
  const double max_t = max_fraction * T_edge.translation().norm();
  const double max_a = max_fraction * Eigen::AngleAxisd(T_edge.rotation()).angle();
  const double len = dt.norm();
  const double st = len > max_t ? (len > 0 ? max_t / len : 0.0) : 1.0;
  const double ang = q_pred.angularDistance(q_meas);
  const double sa = ang > max_a ? (ang > 0 ? max_a / ang : 0.0) : 1.0;
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() = T_pred.translation() + st * dt;
  out.linear() = q_pred.slerp(sa, q_meas).normalized().toRotationMatrix();
  return out;
}

std::vector<std::size_t> select_glc_candidates(std::size_t n, std::size_t iteration, int blocks) {
  std::vector<std::size_t> out;
  if (n == 0 || blocks < 1) return out;
  const std::size_t B = static_cast<std::size_t>(blocks);
  if (n <= B) {
    for (std::size_t i = 0; i < n; ++i) out.push_back(i);
    return out;
  }
  for (std::size_t b = 0; b < B; ++b) {
    const std::size_t lo = b * n / B, hi = (b + 1) * n / B;
    if (hi <= lo) continue;
    out.push_back(lo + iteration % (hi - lo));
  }
  return out;
}

std::vector<std::int64_t> glc_keyframes_to_test(const std::vector<std::int64_t>& recency,
                                                std::int64_t self_id, std::size_t iteration,
                                                const LoopOptions& options) {
  std::vector<std::int64_t> older;
  for (std::int64_t id : recency)
    if (id != self_id) older.push_back(id);
  const std::size_t excl =
      std::min<std::size_t>(older.size(), static_cast<std::size_t>(options.glc_exclude_latest));
  older.resize(older.size() - excl);
  std::vector<std::int64_t> out;
  for (std::size_t idx : select_glc_candidates(older.size(), iteration, options.glc_blocks))
    out.push_back(older[idx]);
  return out;
}

bool accept_glc_match(const LoopOptions& options, std::size_t n_features, std::size_t matches,
                      double inlier_ratio, std::size_t inliers, std::size_t min_inliers) {
  return n_features > 0 &&
         static_cast<double>(matches) >=
             options.glc_min_match_fraction * static_cast<double>(n_features) &&
         inlier_ratio >= options.glc_min_inlier_fraction && inliers >= min_inliers;
}

}  // namespace rgbdquad::slam
