// Gravity consistency: checks an accelerometer-to-camera rotation against ground truth. With the
// true camera attitude R_world_cam, a correct rotation makes R_world_cam * f_cam (the specific
// force in the world frame) point the same way at every frame - up, gravity's opposite - up to
// the motion's own acceleration and the sensor's noise; a wrong one makes it swing with the
// camera. The spread of that direction, in degrees, is the check (`slam-eval accel-check`).
//
// Stateless functions; thread-safe.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

namespace rgbdquad::slam {

/// How far the world-frame specific-force directions stray from their mean direction.
struct GravitySpread {
  std::size_t samples = 0;
  Eigen::Vector3d mean_direction_world = Eigen::Vector3d::Zero();  ///< unit
  double rms_deg = 0.0;  ///< root mean square angle to the mean direction
  double p95_deg = 0.0;  ///< 95th percentile of that angle
  double max_deg = 0.0;
};

/// Spread of the directions R_world_cam[i] * f_cam[i]. Needs equal sizes, at least 2 samples,
/// finite non-zero vectors; nullopt otherwise (or when the directions cancel out).
std::optional<GravitySpread> gravity_direction_spread(
    const std::vector<Eigen::Matrix3d>& R_world_cam, const std::vector<Eigen::Vector3d>& f_cam);

/// The 24 rotations that map axes onto axes (signed permutations with determinant +1): the
/// candidates for how a sensor is mounted on the camera body, row-major as
/// AccelGateOptions::R_cam_sensor.
std::vector<std::array<double, 9>> axis_aligned_rotations();

}  // namespace rgbdquad::slam
