// Gravity consistency: the spread is 0 for a right rotation, large for a wrong one, and the 24
// axis-aligned candidates are distinct rotations.
#include "slam/motion/gravity_consistency.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <random>
#include <set>

namespace rgbdquad::slam {
namespace {

/// A camera turning through many attitudes; the sensor reads up (world +z) in its own frame.
struct Attitudes {
  std::vector<Eigen::Matrix3d> R_world_cam;
  std::vector<Eigen::Vector3d> f_cam;
};

Attitudes turning_camera(const Eigen::Matrix3d& R_cam_sensor_true) {
  Attitudes a;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(-0.6, 0.6);
  const Eigen::Vector3d up_world(0, 0, 9.81);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(angle(rng) * 5, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    a.R_world_cam.push_back(R);
    const Eigen::Vector3d f_sensor = R_cam_sensor_true.transpose() * R.transpose() * up_world;
    a.f_cam.push_back(f_sensor);  // as read, before any rotation into the camera frame
  }
  return a;
}

Eigen::Matrix3d row_major(const std::array<double, 9>& r) {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r.data());
}

TEST(GravityConsistency, GivenTheTrueRotationThenZeroSpreadAndUp) {
  // GIVEN a sensor mounted with x left, y up, z forward on an optical camera (x right, y down)
  const Eigen::Matrix3d R_cam_sensor = Eigen::Vector3d(-1, -1, 1).asDiagonal();
  Attitudes a = turning_camera(R_cam_sensor);
  for (Eigen::Vector3d& f : a.f_cam) f = R_cam_sensor * f;
  // WHEN the spread is computed with that rotation applied
  const auto s = gravity_direction_spread(a.R_world_cam, a.f_cam);
  // THEN the directions coincide, pointing up
  ASSERT_TRUE(s);
  EXPECT_EQ(s->samples, 50u);
  EXPECT_LT(s->max_deg, 1e-6);
  EXPECT_GT(s->mean_direction_world.z(), 0.999999);
}

TEST(GravityConsistency, GivenEachCandidateThenOnlyTheTrueOneHasNoSpread) {
  const auto candidates = axis_aligned_rotations();
  const Eigen::Matrix3d truth = row_major(candidates[5]);
  const Attitudes raw = turning_camera(truth);
  int zero_spread = 0;
  for (const auto& c : candidates) {
    std::vector<Eigen::Vector3d> f_cam;
    for (const Eigen::Vector3d& f : raw.f_cam) f_cam.push_back(row_major(c) * f);
    const auto s = gravity_direction_spread(raw.R_world_cam, f_cam);
    ASSERT_TRUE(s);
    if (s->rms_deg < 1e-6) {
      ++zero_spread;
      EXPECT_TRUE(row_major(c).isApprox(truth));
    } else {
      EXPECT_GT(s->rms_deg, 5.0);  // the wrong mountings swing with the camera
    }
  }
  EXPECT_EQ(zero_spread, 1);
}

TEST(GravityConsistency, GivenAxisAlignedRotationsThen24DistinctProperRotations) {
  const auto candidates = axis_aligned_rotations();
  ASSERT_EQ(candidates.size(), 24u);
  std::set<std::array<double, 9>> unique(candidates.begin(), candidates.end());
  EXPECT_EQ(unique.size(), 24u);
  for (const auto& c : candidates) {
    const Eigen::Matrix3d R = row_major(c);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_TRUE((R * R.transpose()).isIdentity(1e-12));
  }
}

TEST(GravityConsistency, GivenBadInputThenNullopt) {
  EXPECT_FALSE(gravity_direction_spread({}, {}));
  EXPECT_FALSE(gravity_direction_spread({Eigen::Matrix3d::Identity()}, {Eigen::Vector3d::UnitZ()}));
  EXPECT_FALSE(gravity_direction_spread({Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity()},
                                        {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero()}));
  EXPECT_FALSE(gravity_direction_spread({Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity()},
                                        {Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitZ()}));
}

}  // namespace
}  // namespace rgbdquad::slam
