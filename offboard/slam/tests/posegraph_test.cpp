// Pose graph: a synthetic loop with injected odometry drift is corrected by one loop edge; a
// false loop closure does not wreck the map thanks to the robust loss; g2o export.
#include "slam/posegraph/posegraph.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace rgbdquad::slam {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Ground truth: N poses on a circle of radius 1 m, camera yawing with the motion.
Eigen::Isometry3d circle_pose(int i, int n) {
  const double a = 2 * kPi * i / n;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(std::cos(a), std::sin(a), 0.1 * std::sin(3 * a));
  T.linear() = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

double max_position_error(const PoseGraph& g, int n) {
  double e = 0;
  for (int i = 0; i < n; ++i)
    e = std::max(e, (g.pose(i).translation() - circle_pose(i, n).translation()).norm());
  return e;
}

Eigen::Matrix<double, 6, 1> sqrt_info(double sigma_t_m, double sigma_r_rad) {
  Eigen::Matrix<double, 6, 1> s;
  s << 1 / sigma_t_m, 1 / sigma_t_m, 1 / sigma_t_m, 1 / sigma_r_rad, 1 / sigma_r_rad,
      1 / sigma_r_rad;
  return s;
}

// Builds the graph from odometry with a small yaw bias per step (drift), initialised by chaining.
PoseGraph drifting_loop(int n, double yaw_bias_rad) {
  PoseGraph g;
  Eigen::Isometry3d chained = circle_pose(0, n);
  g.add_node(0, chained);
  const Eigen::Isometry3d bias(Eigen::AngleAxisd(yaw_bias_rad, Eigen::Vector3d::UnitZ()));
  for (int i = 1; i < n; ++i) {
    const Eigen::Isometry3d rel = circle_pose(i - 1, n).inverse() * circle_pose(i, n) * bias;
    chained = chained * rel;
    g.add_node(i, chained);
    PoseGraphEdge e;
    e.from = i - 1;
    e.to = i;
    e.T_from_to = rel;
    e.sqrt_information = sqrt_info(0.01, 0.01);
    EXPECT_TRUE(g.add_edge(e));
  }
  return g;
}

TEST(PoseGraph, GivenDriftingLoopWhenTrueLoopEdgeAddedThenDriftCorrected) {
  const int n = 40;
  PoseGraph g = drifting_loop(n, 0.002);  // 0.11 deg per step: ~13 cm drift at the far side
  const double before = max_position_error(g, n);
  PoseGraphEdge loop;
  loop.from = 0;
  loop.to = n - 1;
  loop.T_from_to = circle_pose(0, n).inverse() * circle_pose(n - 1, n);
  loop.sqrt_information = sqrt_info(0.01, 0.01);
  loop.loop = true;
  ASSERT_TRUE(g.add_edge(loop));
  std::string report;
  ASSERT_GE(g.optimize(PoseGraphOptions{}, &report), 0.0) << report;
  const double after = max_position_error(g, n);
  EXPECT_GT(before, 0.05);
  EXPECT_LT(after, 0.25 * before) << "before " << before << " after " << after;
  // The fixed first node stays put.
  EXPECT_TRUE(g.pose(0).isApprox(circle_pose(0, n), 1e-12));
}

// A chain whose every edge carries a small roll bias (the tilt drift vision alone leaves free),
// each node measuring gravity (the world's -Z) truthfully in its camera frame.
// Tilt of pose T against the truth: the angle between the two down directions in the camera.
double tilt_rad(const Eigen::Isometry3d& T, const Eigen::Isometry3d& T_true,
                const Eigen::Vector3d& down_world) {
  const double c =
      (T.linear().transpose() * down_world).dot(T_true.linear().transpose() * down_world);
  return std::acos(std::clamp(c, -1.0, 1.0));
}

// Heading error: the yaw of the camera's x axis in the world's horizontal plane.
double yaw_error_rad(const Eigen::Isometry3d& T, const Eigen::Isometry3d& T_true) {
  const Eigen::Vector3d x = T.linear().col(0), x_true = T_true.linear().col(0);
  return std::abs(
      std::remainder(std::atan2(x.y(), x.x()) - std::atan2(x_true.y(), x_true.x()), 2 * kPi));
}

// A chain whose every edge carries a small roll bias (the tilt drift vision alone leaves free),
// each node measuring gravity (the world's -Z) truthfully in its camera frame.
TEST(PoseGraph, GravityFactorsHoldTheTiltTheEdgesDriftInAndLeaveYawAlone) {
  const int n = 20;
  const Eigen::Vector3d down_world = -Eigen::Vector3d::UnitZ();
  for (const bool with_gravity : {false, true}) {
    SCOPED_TRACE(with_gravity ? "gravity factors" : "edges only");
    PoseGraph g;
    Eigen::Isometry3d chained = circle_pose(0, n);
    g.add_node(0, chained);
    const Eigen::Isometry3d roll_bias(Eigen::AngleAxisd(0.005, Eigen::Vector3d::UnitX()));
    double tilt_before = 0;
    for (int i = 1; i < n; ++i) {
      const Eigen::Isometry3d rel = circle_pose(i - 1, n).inverse() * circle_pose(i, n) * roll_bias;
      chained = chained * rel;
      g.add_node(i, chained);
      tilt_before = std::max(tilt_before, tilt_rad(chained, circle_pose(i, n), down_world));
      PoseGraphEdge e;
      e.from = i - 1;
      e.to = i;
      e.T_from_to = rel;
      e.sqrt_information = sqrt_info(0.01, 0.01);
      ASSERT_TRUE(g.add_edge(e));
      if (with_gravity) {
        GravityObservation obs;
        obs.down_cam = circle_pose(i, n).linear().transpose() * down_world;
        obs.sigma_rad = 0.01;  // as strong as an edge's rotation
        ASSERT_TRUE(g.add_gravity(PoseGraphGravity{i, down_world, obs}));
      }
    }
    std::string report;
    ASSERT_GE(g.optimize(PoseGraphOptions{}, &report), 0.0) << report;
    double tilt_after = 0, yaw_after = 0;
    for (int i = 0; i < n; ++i) {
      tilt_after = std::max(tilt_after, tilt_rad(g.pose(i), circle_pose(i, n), down_world));
      yaw_after = std::max(yaw_after, yaw_error_rad(g.pose(i), circle_pose(i, n)));
    }
    ASSERT_GT(tilt_before, 0.02);  // the bias did tilt the chain (> 1 deg somewhere)
    if (with_gravity) {
      // THEN most of the tilt is gone and the heading stays what the edges say
      EXPECT_LT(tilt_after, 0.3 * tilt_before) << tilt_after << " vs " << tilt_before;
      EXPECT_LT(yaw_after, 0.01) << yaw_after;
    } else {
      // THEN the edges alone keep the chain's tilt
      EXPECT_GT(tilt_after, 0.9 * tilt_before) << tilt_after << " vs " << tilt_before;
    }
  }
}

TEST(PoseGraph, RefusesGravityOnUnknownNodesOrWithoutASigma) {
  PoseGraph g;
  g.add_node(0, Eigen::Isometry3d::Identity());
  GravityObservation obs;
  EXPECT_FALSE(g.add_gravity(PoseGraphGravity{7, -Eigen::Vector3d::UnitZ(), obs}));
  obs.sigma_rad = 0;
  EXPECT_FALSE(g.add_gravity(PoseGraphGravity{0, -Eigen::Vector3d::UnitZ(), obs}));
  obs.sigma_rad = 0.1;
  EXPECT_TRUE(g.add_gravity(PoseGraphGravity{0, -Eigen::Vector3d::UnitZ(), obs}));
}

TEST(PoseGraph, GivenFalseLoopClosureThenRobustLossKeepsMapIntact) {
  const int n = 40;
  auto build = [&](bool robust) {
    PoseGraph g = drifting_loop(n, 0.0);  // perfect odometry
    PoseGraphEdge bad;
    bad.from = 5;
    bad.to = 25;  // claims two poses ~1.9 m apart coincide
    bad.T_from_to = Eigen::Isometry3d::Identity();
    bad.sqrt_information = sqrt_info(0.01, 0.01);
    bad.loop = robust;
    EXPECT_TRUE(g.add_edge(bad));
    EXPECT_GE(g.optimize(PoseGraphOptions{}), 0.0);
    return max_position_error(g, n);
  };
  const double plain = build(false), robust = build(true);
  EXPECT_GT(plain, 0.3);    // least squares lets the false edge pull the map apart
  EXPECT_LT(robust, 0.02);  // Cauchy loss: the map stays within 2 cm
}

TEST(PoseGraph, RejectsEdgesToUnknownNodesAndExportsG2o) {
  PoseGraph g;
  g.add_node(0, Eigen::Isometry3d::Identity());
  g.add_node(1, Eigen::Isometry3d::Identity());
  PoseGraphEdge e;
  e.from = 0;
  e.to = 7;
  EXPECT_FALSE(g.add_edge(e));
  e.to = 1;
  EXPECT_TRUE(g.add_edge(e));
  const std::string text = g.to_g2o();
  EXPECT_NE(text.find("VERTEX_SE3:QUAT 1 "), std::string::npos);
  EXPECT_NE(text.find("EDGE_SE3:QUAT 0 1 "), std::string::npos);
  EXPECT_NE(text.find("FIX 0"), std::string::npos);
}

}  // namespace
}  // namespace rgbdquad::slam
