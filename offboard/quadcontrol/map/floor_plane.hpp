// Floor detection and the floor-aligned world frame (thesis Section 3.3.3: at start-up the craft
// is elevated with a clear view of the floor; the Kinect is mounted at an angle).
//
// fit_floor_plane(): RANSAC (seeded, deterministic) over 3D points in the camera frame, keeping
// only planes whose normal is within max_tilt_deg of the expected "up" direction in the camera
// frame (from the mount angle), so a wall is never taken for the floor. Among those, the plane
// farthest below the camera wins ties of similar support (a table top is above the floor).
// floor_frame_from_plane(): T_floor_cam, mapping camera points to a world frame with z up (height
// above the floor), origin under the camera, x along the optical axis projected on the floor.
// Pure functions; thread-safe.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rgbdquad::quadcontrol {

struct FloorPlaneOptions {
  int iterations = 200;              ///< P(miss) < 1e-6 for a floor with >= 25 % of the points
  double inlier_distance_m = 0.02;   ///< ~ Kinect depth noise at 2 m (Khoshelham 2012)
  double max_tilt_deg = 30.0;        ///< normal vs expected up: tolerates mount-angle error
  double min_inlier_fraction = 0.1;  ///< below this the floor is not visible enough to trust
  std::uint32_t seed = 1;            ///< RANSAC seed (deterministic runs)
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

/// Plane n . p + d = 0 in the camera frame, n unit, oriented so the camera is on the +n side
/// (d = camera height above the plane, > 0).
struct FloorPlane {
  Eigen::Vector3d normal_cam = Eigen::Vector3d::UnitZ();
  double d_m = 0.0;
  std::size_t inliers = 0;
  double inlier_fraction = 0.0;
};

std::optional<FloorPlane> fit_floor_plane(const std::vector<Eigen::Vector3d>& points_cam,
                                          const Eigen::Vector3d& expected_up_cam,
                                          const FloorPlaneOptions& options);

/// The Kinect's mount, R_body_cam: camera (x right, y down, z forward) -> body FRD, for a camera
/// looking along body x and pitched down by mount_pitch_down_deg (the mount
/// hil/kinect_emulator/poses.py renders).
Eigen::Matrix3d rotation_body_cam(double mount_pitch_down_deg);

/// Expected up direction in the camera frame (x right, y down, z forward) for a camera pitched
/// down by mount_pitch_down_deg: body up (FRD -z) through rotation_body_cam().
Eigen::Vector3d expected_up_in_camera(double mount_pitch_down_deg);

/// T_floor_cam from the plane: maps camera points into the floor frame (z = height above floor).
Eigen::Isometry3d floor_frame_from_plane(const FloorPlane& plane);

}  // namespace rgbdquad::quadcontrol
