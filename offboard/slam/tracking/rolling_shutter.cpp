// Rolling-shutter correction of a frame's features; see rolling_shutter.hpp.
#include "slam/tracking/rolling_shutter.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace rgbdquad::slam {

bool unroll_rotation(FrameFeatures* features, const Eigen::Vector3d& omega_cam_rad_per_s,
                     double readout_s, int rows) {
  if (!features || rows <= 1 || !(readout_s > 0) || !omega_cam_rad_per_s.allFinite()) return false;
  const double row_s = readout_s / rows;
  const double mid_row = 0.5 * (rows - 1);
  // Largest rotation any row gets, in radians; below 0.01 px at fx ~500 it changes nothing.
  if (omega_cam_rad_per_s.norm() * 0.5 * readout_s * 500.0 < 0.01) return false;
  for (std::size_t i = 0; i < features->points_cam_m.size(); ++i) {
    // A row exposed dt after the middle row saw the scene from a camera turned by omega * dt:
    // p_mid = R(omega * dt) * p_row (camera-frame angular velocity, right-multiplied motion).
    const double dt = (features->keypoints[i].pt.y - mid_row) * row_s;
    const Eigen::Vector3d rotvec = omega_cam_rad_per_s * dt;
    const double angle = rotvec.norm();
    if (!(angle > 0)) continue;
    features->points_cam_m[i] =
        Eigen::AngleAxisd(angle, rotvec / angle) * features->points_cam_m[i];
  }
  return true;
}

}  // namespace rgbdquad::slam
