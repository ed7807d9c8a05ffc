// The acceleration bound on a tracked pose: how far the camera can have left its recent
// constant-velocity path in a gap dt. The velocity is the mean over a baseline of at least
// `baseline_s` of tracked positions (not one frame interval: one interval's velocity carries the
// pose noise of two frames divided by 33 ms, a second difference of ~2.5x the per-frame noise that
// grows with every extrapolated interval). For constant acceleration a, the mean velocity over
// the baseline B is the velocity B/2 ago, so the extrapolation after dt is off by
// a B dt / 2 + a dt^2 / 2: the bound is margin + a dt (dt + B) / 2.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>

namespace rgbdquad::slam {

struct MotionBoundOptions {
  double margin_m = 0.05;  ///< pose noise of the new fit (TrackerOptions::motion_margin_m)
  double max_acceleration_m_per_s2 = 5.0;  ///< see TrackerOptions::max_acceleration_m_per_s2
  double baseline_s = 0.1;                 ///< 3 frame intervals at 30 fps: velocity noise / 3
  std::size_t capacity = 16;               ///< positions kept (bounded; > baseline at 30 fps)
};

struct MotionBoundCheck {
  bool checked = false;     ///< false: fewer than two positions since the last reset
  double deviation_m = -1;  ///< distance of the position from the extrapolated path
  double bound_m = -1;
  bool within() const { return !checked || deviation_m <= bound_m; }
};

/// The last tracked positions (one world frame: reset on a loop correction or relocalisation).
class MotionBound {
 public:
  explicit MotionBound(MotionBoundOptions options = {}) : options_(options) {}
  void reset() { history_.clear(); }
  /// Appends a tracked position; stamps must increase (an older or equal stamp resets first).
  void add(double stamp_s, const Eigen::Vector3d& p_world_m);
  /// Whether `p_world_m` at `stamp_s` is within the bound of the path so far.
  MotionBoundCheck check(double stamp_s, const Eigen::Vector3d& p_world_m) const;

 private:
  struct Sample {
    double stamp_s;
    Eigen::Vector3d p_world_m;
  };
  MotionBoundOptions options_;
  std::deque<Sample> history_;
};

}  // namespace rgbdquad::slam
