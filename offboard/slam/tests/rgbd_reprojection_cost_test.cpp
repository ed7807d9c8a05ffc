// The analytic RGB-D reprojection cost against the same residual under Ceres's automatic
// differentiation: values and both Jacobians, at rotations from zero to near pi and at the depth
// floor.
#include "slam/mapping/rgbd_reprojection_cost.hpp"

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>

namespace rgbdquad::slam {
namespace {

/// The residual written once more, generically, for automatic differentiation.
struct AutoDiffReference {
  Eigen::Vector3d z, inv_sigma;
  CameraModel cam;
  template <typename T>
  bool operator()(const T* pose, const T* point, T* r) const {
    T pc[3];
    ceres::AngleAxisRotatePoint(pose, point, pc);
    for (int i = 0; i < 3; ++i) pc[i] += pose[3 + i];
    if (pc[2] < T(RgbdReprojectionCost::kMinDepthM)) pc[2] = T(RgbdReprojectionCost::kMinDepthM);
    const T iz = T(1.0) / pc[2];
    r[0] = (T(cam.fx_px) * pc[0] * iz + T(cam.cx_px) - T(z.x())) * T(inv_sigma.x());
    r[1] = (T(cam.fy_px) * pc[1] * iz + T(cam.cy_px) - T(z.y())) * T(inv_sigma.y());
    r[2] = (T(cam.bf_px_m) * iz - T(z.z())) * T(inv_sigma.z());
    return true;
  }
};

using AutoDiffReferenceCost = ceres::AutoDiffCostFunction<AutoDiffReference, 3, 6, 3>;

CameraModel fr1_like() {
  CameraModel c;
  c.fx_px = 517.3;
  c.fy_px = 516.5;
  c.cx_px = 318.6;
  c.cy_px = 255.3;
  c.bf_px_m = 40.0;
  return c;
}

struct Evaluated {
  std::array<double, 3> r{};
  std::array<double, 18> J_pose{};
  std::array<double, 9> J_point{};
};

Evaluated evaluate(const AutoDiffReferenceCost& f, const std::array<double, 6>& pose,
                   const std::array<double, 3>& point) {
  Evaluated e;
  const double* params[] = {pose.data(), point.data()};
  double* jac[] = {e.J_pose.data(), e.J_point.data()};
  EXPECT_TRUE(f.Evaluate(params, e.r.data(), jac));
  return e;
}

/// The analytic cost's rotation and translation Jacobians (3 x 3 each, row-major) laid side by
/// side as the reference's 3 x 6 pose Jacobian.
Evaluated evaluate(const RgbdReprojectionCost& f, const std::array<double, 6>& pose,
                   const std::array<double, 3>& point) {
  Evaluated e;
  std::array<double, 9> J_rotation{}, J_translation{};
  const double* params[] = {pose.data(), pose.data() + 3, point.data()};
  double* jac[] = {J_rotation.data(), J_translation.data(), e.J_point.data()};
  EXPECT_TRUE(f.Evaluate(params, e.r.data(), jac));
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 3; ++col) {
      e.J_pose[row * 6 + col] = J_rotation[row * 3 + col];
      e.J_pose[row * 6 + 3 + col] = J_translation[row * 3 + col];
    }
  return e;
}

void expect_same(const Evaluated& a, const Evaluated& b, double tol) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a.r[i], b.r[i], tol * (1 + std::abs(b.r[i]))) << i;
  for (int i = 0; i < 18; ++i)
    EXPECT_NEAR(a.J_pose[i], b.J_pose[i], tol * (1 + std::abs(b.J_pose[i]))) << "pose " << i;
  for (int i = 0; i < 9; ++i)
    EXPECT_NEAR(a.J_point[i], b.J_point[i], tol * (1 + std::abs(b.J_point[i]))) << "point " << i;
}

class RgbdReprojectionCostTest : public ::testing::Test {
 protected:
  const CameraModel cam_ = fr1_like();
  const Eigen::Vector3d z_{300.0, 240.0, 18.0};
  const Eigen::Vector3d sigma_{1.2, 1.2, 0.3};
  RgbdReprojectionCost analytic_{z_, sigma_, cam_};
  AutoDiffReferenceCost autodiff_{new AutoDiffReference{z_, sigma_.cwiseInverse(), cam_}};
};

TEST_F(RgbdReprojectionCostTest, MatchesAutomaticDifferentiationOverRandomPosesAndPoints) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int n = 0; n < 200; ++n) {
    Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
    axis.normalize();
    const double angle = 3.1 * (n % 20) / 19.0;  // 0 .. 3.1 rad
    const Eigen::Vector3d w = axis * angle;
    const std::array<double, 6> pose = {w.x(), w.y(), w.z(), unit(rng), unit(rng), 0.5 * unit(rng)};
    // A point 1-4 m in front of the camera, expressed in the world frame.
    const Eigen::Vector3d p_cam(unit(rng), unit(rng), 2.5 + 1.5 * unit(rng));
    const Eigen::Matrix3d R =
        angle > 0 ? Eigen::AngleAxisd(angle, axis).toRotationMatrix() : Eigen::Matrix3d::Identity();
    const Eigen::Vector3d X = R.transpose() * (p_cam - Eigen::Vector3d(pose[3], pose[4], pose[5]));
    expect_same(evaluate(analytic_, pose, {X.x(), X.y(), X.z()}),
                evaluate(autodiff_, pose, {X.x(), X.y(), X.z()}), 1e-9);
  }
}

TEST_F(RgbdReprojectionCostTest, MatchesAtTinyRotationsWhereTheSeriesHolds) {
  // Ceres's own rotation is first order below 1.5e-8 rad, so its Jacobian is only that accurate
  // there: the reference is exact at 0 and 1e-12 rad, and uses Rodrigues from 5e-5 rad on, either
  // side of the series' 1e-4 rad switch.
  for (const double angle : {0.0, 1e-12, 5e-5, 0.99e-4, 1.01e-4, 2e-4}) {
    const Eigen::Vector3d w = angle * Eigen::Vector3d(0.6, -0.48, 0.64);
    const std::array<double, 6> pose = {w.x(), w.y(), w.z(), 0.1, -0.2, 0.3};
    const std::array<double, 3> point = {0.4, -0.3, 2.2};
    expect_same(evaluate(analytic_, pose, point), evaluate(autodiff_, pose, point), 1e-9);
  }
}

TEST_F(RgbdReprojectionCostTest, IsFiniteAndFlatInDepthBehindTheCamera) {
  const std::array<double, 6> pose = {0.1, 0.2, -0.1, 0.0, 0.0, 0.0};
  const std::array<double, 3> point = {0.3, 0.1, -1.0};  // behind the camera
  const Evaluated a = evaluate(analytic_, pose, point);
  expect_same(a, evaluate(autodiff_, pose, point), 1e-9);
  for (double v : a.r) EXPECT_TRUE(std::isfinite(v));
  for (double v : a.J_pose) EXPECT_TRUE(std::isfinite(v));
}

TEST_F(RgbdReprojectionCostTest, ResidualOnlyEvaluationNeedsNoJacobianStorage) {
  const std::array<double, 6> pose = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  const std::array<double, 3> point = {0.0, 0.0, 2.0};
  const double* params[] = {pose.data(), pose.data() + 3, point.data()};
  std::array<double, 3> r{};
  ASSERT_TRUE(analytic_.Evaluate(params, r.data(), nullptr));
  EXPECT_NEAR(r[0], (cam_.cx_px - z_.x()) / sigma_.x(), 1e-12);
  EXPECT_NEAR(r[2], (cam_.bf_px_m / 2.0 - z_.z()) / sigma_.z(), 1e-12);
}

}  // namespace
}  // namespace rgbdquad::slam
