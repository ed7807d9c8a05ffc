// Motion-only optimisation of one camera pose against known 3D points: Gauss-Newton on the RGB-D
// reprojection error (u, v, disparity; see CameraModel) with a Huber kernel, in rounds that
// re-classify outliers by the chi-square test (ORB-SLAM2's PoseOptimization scheme: 4 rounds of
// 10 iterations, outliers excluded from the next round but re-tested).
//
// Stateless and thread-safe.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "slam/map/map.hpp"

namespace rgbdquad::slam {

struct PoseObservation {
  Eigen::Vector3d p_world_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d measurement = Eigen::Vector3d::Zero();  ///< (u px, v px, disparity px)
  Eigen::Vector3d sigma_px = Eigen::Vector3d::Ones();     ///< sigmas of (u, v, disparity)
  /// A keypoint without a depth reading: (u, v) only, the disparity ignored, and the outlier test
  /// at the 2-degree-of-freedom bound (kChi2Mono95, ORB-SLAM2's for its monocular edges).
  bool monocular = false;
};

/// Gravity measured in the camera frame against the map's gravity direction: a residual on the
/// camera's roll and pitch only (rotation about gravity and position are untouched).
struct GravityPrior {
  Eigen::Vector3d down_world = Eigen::Vector3d::UnitY();
  Eigen::Vector3d down_cam = Eigen::Vector3d::UnitY();
  double sigma_rad = 1.0;
};

/// A rolling-shutter camera: row r of the image is exposed `row_time_s[i]` after the middle row
/// (per observation, same order), and the camera turns at the angular velocity omega (camera
/// frame) over the readout. The fit then estimates omega with the pose, from how the rows of the
/// frame disagree; a keypoint seen at row time t sees the point R(omega t)^T p_cam. The prior
/// keeps omega near a predicted rate where the rows say little (few keypoints, a narrow band).
struct RollingShutterModel {
  std::vector<double> row_time_s;
  Eigen::Vector3d omega_prior_rad_per_s = Eigen::Vector3d::Zero();
  double omega_sigma_rad_per_s = 1.0;
};

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations_per_round = 10;
  double chi2_outlier = kChi2Rgbd95;
  std::optional<GravityPrior> gravity;  ///< slam/tracking/gravity_prior.hpp
  std::optional<RollingShutterModel> rolling_shutter;
};

struct PoseOptimizerResult {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  std::vector<bool> inlier;
  int inliers = 0;
  /// The camera's angular velocity over the readout (with a RollingShutterModel; else zero).
  Eigen::Vector3d omega_cam_rad_per_s = Eigen::Vector3d::Zero();
  bool ok =
      false;  ///< false when degenerate (fewer than 3 usable observations or a singular system)
};

PoseOptimizerResult optimize_pose(const Eigen::Isometry3d& T_cam_world_init,
                                  const std::vector<PoseObservation>& observations,
                                  const CameraModel& camera,
                                  const PoseOptimizerOptions& options = {});

/// Applies a left increment: exp(delta) * T, delta = (rotation vector rad, translation m).
Eigen::Isometry3d apply_left_increment(const Eigen::Matrix<double, 6, 1>& delta,
                                       const Eigen::Isometry3d& T);

}  // namespace rgbdquad::slam
