// RGB-D reprojection residual; see rgbd_reprojection_cost.hpp.
#include "slam/mapping/rgbd_reprojection_cost.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace rgbdquad::slam {

namespace {

using Jacobian = Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>;

/// Rodrigues coefficients of w: sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3 (t = |w|).
/// Below 1e-4 rad they use their Taylor series (error < 1e-17), as the closed forms lose all
/// digits to cancellation there.
struct RotationCoefficients {
  double a, b, c;
  explicit RotationCoefficients(const Eigen::Vector3d& w) {
    const double theta2 = w.squaredNorm();
    const double theta = std::sqrt(theta2);
    if (theta < 1e-4) {
      a = 1.0 - theta2 / 6.0;
      b = 0.5 - theta2 / 24.0;
      c = 1.0 / 6.0 - theta2 / 120.0;
    } else {
      const double s = std::sin(theta), co = std::cos(theta);
      a = s / theta;
      b = (1.0 - co) / theta2;
      c = (theta - s) / (theta2 * theta);
    }
  }
};

}  // namespace

RgbdReprojectionCost::RgbdReprojectionCost(const Eigen::Vector3d& measurement,
                                           const Eigen::Vector3d& sigma_px,
                                           const CameraModel& camera)
    : z_(measurement), inv_sigma_(sigma_px.cwiseInverse()), camera_(camera) {}

bool RgbdReprojectionCost::Evaluate(double const* const* parameters, double* residuals,
                                    double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> w(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> X(parameters[2]);
  const RotationCoefficients k(w);
  const Eigen::Matrix3d W = skew(w);
  const Eigen::Matrix3d W2 = W * W;
  const Eigen::Matrix3d R = Eigen::Matrix3d::Identity() + k.a * W + k.b * W2;
  Eigen::Vector3d pc = R * X + t;
  const bool floored = pc.z() < kMinDepthM;
  if (floored) pc.z() = kMinDepthM;
  Eigen::Map<Eigen::Vector3d>{residuals} = (camera_.project(pc) - z_).cwiseProduct(inv_sigma_);
  if (!jacobians) return true;
  // d r / d p_c, whitened; the z column is zero where the floor holds z constant.
  Eigen::Matrix3d dr_dpc = inv_sigma_.asDiagonal() * camera_.project_jacobian(pc);
  if (floored) dr_dpc.col(2).setZero();
  if (jacobians[0]) {
    // d p_c / d w = -R [X]x Jr(w), with the right Jacobian of SO(3)
    // Jr(w) = I - b [w]x + c [w]x^2: R(w + dw) = R(w) exp(Jr(w) dw) to first order.
    const Eigen::Matrix3d Jr = Eigen::Matrix3d::Identity() - k.b * W + k.c * W2;
    Jacobian{jacobians[0]} = dr_dpc * (-R * skew(X) * Jr);
  }
  if (jacobians[1]) Jacobian{jacobians[1]} = dr_dpc;
  if (jacobians[2]) Jacobian{jacobians[2]} = dr_dpc * R;
  return true;
}

}  // namespace rgbdquad::slam
