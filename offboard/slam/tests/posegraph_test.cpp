// Pose graph: a synthetic loop with injected odometry drift is corrected by one loop edge; a
// false loop closure does not wreck the map thanks to the robust loss; g2o export.
#include "slam/posegraph/posegraph.hpp"

#include <gtest/gtest.h>

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
