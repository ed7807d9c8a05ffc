// Whitened RGB-D reprojection residual of one keyframe observation, with analytic Jacobians:
//   p_c = R(w) X + t,  r = ((fx x/z + cx - u) / su, (fy y/z + cy - v) / sv, (bf/z - d) / sd)
// over three parameter blocks of three: w and t, the angle-axis and translation of T_cam_world,
// and X, the point in the world (m). Why it is written this way, both for local BA's speed:
//  - three blocks of three: Ceres's Schur eliminator has compiled fixed-size kernels for
//    (3 residuals, 3-wide point, 3-wide pose blocks) but none for a 6-wide pose, where it falls
//    back to dynamic-size matrices;
//  - analytic Jacobians: automatic differentiation carries 9-wide dual numbers through the
//    rotation of every observation; the closed form needs the rotation matrix and the SO(3)
//    right Jacobian.
// z is floored at 1 mm to keep the residual finite, and the floor is constant (zero derivative),
// as it was under automatic differentiation: such an edge is an outlier the chi-square test drops.
//
// Thread safety: immutable after construction.
#pragma once

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

#include "slam/map/map.hpp"

namespace rgbdquad::slam {

class RgbdReprojectionCost final : public ceres::SizedCostFunction<3, 3, 3, 3> {
 public:
  /// `measurement` (u px, v px, disparity px), `sigma_px` its standard deviations.
  RgbdReprojectionCost(const Eigen::Vector3d& measurement, const Eigen::Vector3d& sigma_px,
                       const CameraModel& camera);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  /// Point depth floor, m, below which the residual is held finite and flat.
  static constexpr double kMinDepthM = 1e-3;

 private:
  Eigen::Vector3d z_;
  Eigen::Vector3d inv_sigma_;
  CameraModel camera_;
};

}  // namespace rgbdquad::slam
