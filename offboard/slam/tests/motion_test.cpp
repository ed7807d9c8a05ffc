// Motion stage: Umeyama recovers a known SE(3); RANSAC survives 50 % outliers; seeds reproduce.
#include "slam/motion/motion.hpp"

#include <gtest/gtest.h>

#include <random>

#include "rgbdquad/camera/tum_cameras.hpp"

namespace rgbdquad::slam {
namespace {

constexpr const rgbdquad::camera::TumCamera& kFr1 =
    rgbdquad::camera::kTumFr1;  // the test frames' camera

Eigen::Isometry3d known_pose() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, -1.0, 0.4).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.12, -0.05, 0.31);
  return T;
}

std::vector<Eigen::Vector3d> random_points(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(0.5, 4.0);
  std::vector<Eigen::Vector3d> p(n);
  for (auto& x : p) x = {xy(rng), xy(rng), z(rng)};
  return p;
}

TEST(Umeyama, GivenExactPairsWhenAlignedThenRecoversTransformTo1e9) {
  const Eigen::Isometry3d T = known_pose();
  const auto src = random_points(50, 1);
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.push_back(T * p);
  auto est = umeyama_rigid(src, dst);
  ASSERT_TRUE(est);
  EXPECT_LT((est->matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  // Weighted version with arbitrary positive weights: the same exact answer.
  std::vector<double> w(src.size());
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = 0.1 + static_cast<double>(i % 7);
  auto est_w = umeyama_rigid(src, dst, w);
  ASSERT_TRUE(est_w);
  EXPECT_LT((est_w->matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Umeyama, GivenDegenerateInputThenNoEstimate) {
  std::vector<Eigen::Vector3d> line = {{0, 0, 1}, {0, 0, 2}, {0, 0, 3}, {0, 0, 4}};
  EXPECT_FALSE(umeyama_rigid(line, line));  // collinear
  EXPECT_FALSE(umeyama_rigid({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}, {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}));
  EXPECT_FALSE(umeyama_rigid(random_points(2, 3), random_points(2, 4)));  // too few
  auto bad = random_points(5, 5);
  bad[2].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(umeyama_rigid(bad, random_points(5, 6)));  // non-finite
}

struct RansacCase {
  RansacSampling sampling;
  const char* name;
};

class RansacOutliers : public ::testing::TestWithParam<RansacCase> {};

TEST_P(RansacOutliers, GivenHalfOutliersWhenEstimatingThenInliersFoundAndPoseAccurate) {
  const Eigen::Isometry3d T = known_pose();
  const std::size_t n = 200;
  const auto src = random_points(n, 11);
  std::mt19937_64 rng(12);
  std::normal_distribution<double> noise(0.0, 0.003);  // 3 mm, Kinect-like at ~1.5 m
  std::vector<Eigen::Vector3d> dst;
  std::vector<bool> is_inlier(n);
  const auto junk = random_points(n, 13);
  for (std::size_t i = 0; i < n; ++i) {
    is_inlier[i] = i % 2 == 0;
    dst.push_back(is_inlier[i] ? T * src[i] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))
                               : junk[i]);
  }
  // Descriptor order for the thesis sampler: inliers first, like good descriptor matches.
  std::vector<int> order;
  for (std::size_t i = 0; i < n; i += 2) order.push_back(static_cast<int>(i));
  for (std::size_t i = 1; i < n; i += 2) order.push_back(static_cast<int>(i));
  RansacOptions o;
  o.sampling = GetParam().sampling;
  o.accept_inlier_ratio = 0.45;
  std::string why;
  auto est = estimate_motion_ransac(src, dst, order, o, 42, &why);
  ASSERT_TRUE(est) << why;
  std::size_t true_inliers = 0;
  for (int i : est->inliers) true_inliers += is_inlier[static_cast<std::size_t>(i)];
  EXPECT_GE(true_inliers, 95u);                       // nearly all 100 real inliers
  EXPECT_LE(est->inliers.size() - true_inliers, 3u);  // junk rarely lands within 3 cm
  EXPECT_TRUE(est->accepted);
  EXPECT_LT((est->T_dst_src.translation() - T.translation()).norm(), 0.002);
  EXPECT_LT(Eigen::AngleAxisd(est->T_dst_src.rotation().transpose() * T.rotation()).angle(), 0.002);
}

INSTANTIATE_TEST_SUITE_P(Samplers, RansacOutliers,
                         ::testing::Values(RansacCase{RansacSampling::kRandom, "random"},
                                           RansacCase{RansacSampling::kThesis, "thesis"}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Ransac, GivenSameSeedThenSameResultAndTooFewPairsRejected) {
  const Eigen::Isometry3d T = known_pose();
  const auto src = random_points(60, 21);
  auto dst = random_points(60, 22);
  for (std::size_t i = 0; i < 30; ++i) dst[i] = T * src[i];
  RansacOptions o;
  auto a = estimate_motion_ransac(src, dst, {}, o, 7, nullptr);
  auto b = estimate_motion_ransac(src, dst, {}, o, 7, nullptr);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->inliers, b->inliers);
  EXPECT_EQ(a->T_dst_src.matrix(), b->T_dst_src.matrix());
  EXPECT_FALSE(a->accepted);  // 50 % < 60 % thesis acceptance
  std::string why;
  EXPECT_FALSE(estimate_motion_ransac(random_points(4, 1), random_points(4, 2), {}, o, 1, &why));
  EXPECT_NE(why.find("too few"), std::string::npos);
}

TEST(ReprojectionRefine, GivenExactPixelsAndNoisyDepthThenRefinedPoseBeatsUmeyama) {
  // GIVEN points seen by two cameras with exact pixels but 1 % depth noise on both sides
  const Eigen::Isometry3d T = known_pose();
  const RansacOptions::Pinhole cam{kFr1.fx_px, kFr1.fy_px, kFr1.cx_px, kFr1.cy_px};
  const auto pts = random_points(150, 31);
  std::mt19937_64 rng(32);
  std::normal_distribution<double> scale(1.0, 0.01);
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<int> all;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3d d = T * pts[i];
    if (d.z() < 0.3) continue;
    src.push_back(pts[i] * scale(rng));  // scaling along the ray keeps the pixel exact
    dst.push_back(d * scale(rng));
    all.push_back(static_cast<int>(src.size() - 1));
  }
  auto ls = umeyama_rigid(src, dst);
  ASSERT_TRUE(ls);
  // WHEN refining on the reprojection error
  const Eigen::Isometry3d refined = refine_reprojection(*ls, src, dst, all, cam, 10, 2.0);
  // THEN the pose is closer to the truth than the 3D least-squares fit
  const double err_ls = (ls->translation() - T.translation()).norm();
  const double err_ref = (refined.translation() - T.translation()).norm();
  EXPECT_LT(err_ref, 0.5 * err_ls) << "ls " << err_ls << " refined " << err_ref;
  // and a camera without intrinsics leaves the input unchanged
  EXPECT_TRUE(
      refine_reprojection(*ls, src, dst, all, RansacOptions::Pinhole{}, 10, 2.0).isApprox(*ls));
}

// The analytic Jacobians of the reprojection refinement against central differences of the
// residual under the solver's own update T' = exp(delta) * T (delta = translation, rotation
// vector).
Eigen::Isometry3d left_increment(const Eigen::Matrix<double, 6, 1>& delta,
                                 const Eigen::Isometry3d& T) {
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  const double angle = delta.tail<3>().norm();
  if (angle > 0)
    step.linear() = Eigen::AngleAxisd(angle, delta.tail<3>() / angle).toRotationMatrix();
  step.translation() = delta.head<3>();
  return step * T;
}

template <typename TermFn>
double worst_jacobian_error(TermFn term, const Eigen::Isometry3d& T, const Eigen::Vector3d& s,
                            const Eigen::Vector3d& d, const RansacOptions::Pinhole& c) {
  const ReprojectionTerm analytic = term(T, s, d, c);
  EXPECT_TRUE(analytic.valid);
  constexpr double kStep = 1e-6;  // metres / radians: central differences, O(h^2) truncation
  double worst = 0;
  for (int k = 0; k < 6; ++k) {
    Eigen::Matrix<double, 6, 1> delta = Eigen::Matrix<double, 6, 1>::Zero();
    delta[k] = kStep;
    const Eigen::Vector2d plus = term(left_increment(delta, T), s, d, c).residual_px;
    const Eigen::Vector2d minus = term(left_increment(-delta, T), s, d, c).residual_px;
    const Eigen::Vector2d numeric = (plus - minus) / (2 * kStep);
    const double scale = std::max(1.0, numeric.cwiseAbs().maxCoeff());
    worst = std::max(worst, (analytic.jacobian.col(k) - numeric).cwiseAbs().maxCoeff() / scale);
  }
  return worst;
}

TEST(ReprojectionRefine, GivenRandomPosesAndPointsThenAnalyticJacobiansMatchNumericDerivatives) {
  const RansacOptions::Pinhole c{kFr1.fx_px, kFr1.fy_px, kFr1.cx_px, kFr1.cy_px};
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-0.5, 0.5), shift(-0.3, 0.3);
  const auto src = random_points(20, 3);
  for (int trial = 0; trial < 10; ++trial) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitX()) *
                  Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitZ()))
                     .toRotationMatrix();
    T.translation() = Eigen::Vector3d(shift(rng), shift(rng), shift(rng));
    for (const auto& s : src) {
      // A destination near T*s (not equal: residuals must be non-zero to exercise every term).
      const Eigen::Vector3d d = T * s + Eigen::Vector3d(shift(rng), shift(rng), shift(rng)) * 0.1;
      if ((T * s).z() < 0.3 || (T.inverse() * d).z() < 0.3) continue;
      EXPECT_LT(worst_jacobian_error(forward_reprojection_term, T, s, d, c), 1e-5);
      EXPECT_LT(worst_jacobian_error(backward_reprojection_term, T, s, d, c), 1e-5);
    }
  }
}

TEST(ReprojectionRefine, GivenAPointBehindTheCameraThenTheTermCarriesNoInformation) {
  const RansacOptions::Pinhole c{kFr1.fx_px, kFr1.fy_px, kFr1.cx_px, kFr1.cy_px};
  const Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  EXPECT_FALSE(forward_reprojection_term(T, {0, 0, 0.05}, {0, 0, 1.0}, c).valid);
  EXPECT_FALSE(backward_reprojection_term(T, {0, 0, 1.0}, {0, 0, -1.0}, c).valid);
  EXPECT_TRUE(forward_reprojection_term(T, {0, 0, 1.0}, {0, 0, 1.0}, c).valid);
}

}  // namespace
}  // namespace rgbdquad::slam
