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
};

/// Gravity measured in the camera frame against the map's gravity direction: a residual on the
/// camera's roll and pitch only (rotation about gravity and position are untouched).
struct GravityPrior {
  Eigen::Vector3d down_world = Eigen::Vector3d::UnitY();
  Eigen::Vector3d down_cam = Eigen::Vector3d::UnitY();
  double sigma_rad = 1.0;
};

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations_per_round = 10;
  double chi2_outlier = kChi2Rgbd95;
  std::optional<GravityPrior> gravity;  ///< slam/tracking/gravity_prior.hpp
};

struct PoseOptimizerResult {
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  std::vector<bool> inlier;
  int inliers = 0;
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
