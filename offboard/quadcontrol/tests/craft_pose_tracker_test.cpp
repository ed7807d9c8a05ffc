// CraftPoseTracker (core/craft_pose_tracker.hpp): SLAM camera poses -> the craft's pose in the
// floor frame -> the controller's input. Table-driven GIVEN/WHEN/THEN tests, time passed in, on a
// synthetic craft: a camera pitched down over a floor (seeded depth points), SLAM's world frame its
// first camera of each session, the tracker's output handed to a real FlightController where the
// controller's verdict matters.
#include "core/craft_pose_tracker.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr std::int64_t kFrameUs = 33'333;      // 30 fps
constexpr std::int64_t kLinkDelayUs = 30'000;  // capture -> received
constexpr double kG = 9.80665;

/// Camera pose in the floor frame (T_floor_cam): at (x, y, z), optical axis heading `yaw_deg`
/// (ccw from +x) and pitched down by `pitch_down_deg`, rolled by `roll_deg` about the optical axis.
Eigen::Isometry3d camera_at(double x_m, double y_m, double z_m, double yaw_deg = 0.0,
                            double pitch_down_deg = 30.0, double roll_deg = 0.0) {
  const double a = pitch_down_deg / kDegPerRad;
  Eigen::Matrix3d level;  // columns: camera x (right), y (down-ish), z (forward-down), yaw 0
  const Eigen::Vector3d z_cam(std::cos(a), 0.0, -std::sin(a));
  const Eigen::Vector3d x_cam(0.0, -1.0, 0.0);
  level.col(0) = x_cam;
  level.col(1) = z_cam.cross(x_cam);
  level.col(2) = z_cam;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(yaw_deg / kDegPerRad, Eigen::Vector3d::UnitZ()).toRotationMatrix() * level *
      Eigen::AngleAxisd(roll_deg / kDegPerRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x_m, y_m, z_m);
  return T;
}

/// Depth points (camera frame) of what the camera sees: the floor 1-4 m ahead, or only a wall 3 m
/// ahead (no floor in view). Seeded, 5 mm noise.
std::vector<Eigen::Vector3d> depth_of(const Eigen::Isometry3d& T_floor_cam, bool floor_in_view,
                                      std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.005);
  const Eigen::Vector3d c = T_floor_cam.translation();
  const Eigen::Vector3d fwd = T_floor_cam.linear().col(2);
  const double yaw = std::atan2(fwd.y(), fwd.x());
  const Eigen::Vector2d ahead(std::cos(yaw), std::sin(yaw)), left(-std::sin(yaw), std::cos(yaw));
  std::vector<Eigen::Vector3d> pts;
  const Eigen::Isometry3d T_cam_floor = T_floor_cam.inverse();
  for (int i = 0; i < 1500; ++i) {
    const double f = floor_in_view ? 1.0 + 3.0 * u(rng) : 3.0 + noise(rng);
    const double l = -1.5 + 3.0 * u(rng);
    const double z = floor_in_view ? noise(rng) : c.z() - 0.5 + 1.5 * u(rng);
    const Eigen::Vector2d xy = c.head<2>() + f * ahead + l * left;
    pts.push_back(T_cam_floor * Eigen::Vector3d(xy.x(), xy.y(), z));
  }
  return pts;
}

/// The hub's side of the tracker, without threads: SLAM results in, the controller fed.
struct Rig {
  explicit Rig(CraftPoseTrackerOptions options = {}) : tracker(options) {}

  /// One SLAM result of camera `T_floor_cam` (true pose) in a session whose world frame is the
  /// camera `T_floor_world_origin`, as the hub takes it (floor search first, then update).
  CraftPoseUpdate slam(const Eigen::Isometry3d& T_floor_cam, bool tracking = true,
                       std::uint64_t session = 1, std::uint32_t corrections = 0,
                       bool floor_in_view = true) {
    now_us += kFrameUs;
    const Eigen::Isometry3d& origin = session == 1 ? world1 : world2;
    std::optional<FloorPlane> candidate;
    if (tracker.searching_floor() && tracking) {
      candidate = tracker.fit_floor(depth_of(T_floor_cam, floor_in_view, seed++));
    }
    const SlamPoseInput in{tracking,    origin.inverse() * T_floor_cam, session,
                           corrections, now_us - kLinkDelayUs,          now_us};
    CraftPoseUpdate out = tracker.update(now_us, in, candidate);
    controller.on_pose(out.controller.sample, out.controller.velocity_m_per_s);
    return out;
  }
  /// The APM hovering level (IMU samples every 20 ms up to now).
  void imu_until_now() {
    for (; imu_us <= now_us; imu_us += 20'000) {
      ImuSample s;
      s.t_us = imu_us;
      s.specific_force_frd_mss = Eigen::Vector3d(0.0, 0.0, -kG);
      tracker.on_imu(s);
    }
  }

  CraftPoseTracker tracker;
  FlightController controller{ControlConfig{}};
  std::int64_t now_us = 1'000'000;
  std::int64_t imu_us = 1'000'000;
  std::uint32_t seed = 1;
  Eigen::Isometry3d world1 = camera_at(0.0, 0.0, 1.2);  ///< the first session's first camera
  Eigen::Isometry3d world2 = Eigen::Isometry3d::Identity();
};

void expect_pose_near(const CraftPose& a, const CraftPose& b, double tol_m) {
  EXPECT_NEAR(a.x_m, b.x_m, tol_m);
  EXPECT_NEAR(a.y_m, b.y_m, tol_m);
  EXPECT_NEAR(a.z_m, b.z_m, tol_m);
  EXPECT_NEAR(wrap_deg(a.yaw_deg - b.yaw_deg), 0.0, 0.5);
}

// ---- floor search -------------------------------------------------------------------------------

struct FloorCase {
  const char* name;
  double pitch_down_deg, roll_deg;  ///< the camera's true tilt (the mount angle is 30 deg)
  int floor_visible_from;           ///< first tracked frame with the floor in view; -1: never
  int untracked_first;              ///< results that are not tracking before the first tracked one
  int expected_set_at;              ///< result index that fixes the floor frame
  bool expected_fallback;
  double expected_height_m;  ///< of the craft at that result
};

class FloorSearch : public ::testing::TestWithParam<FloorCase> {};

TEST_P(FloorSearch, GivenTheFirstFramesWhenSearchingTheFloorThenItIsFoundOrFallsBackInTime) {
  const FloorCase c = GetParam();
  Rig rig;
  // GIVEN a craft creeping forward at 1.2 m, 1 cm per frame, its world frame the first camera
  auto camera = [&](int i) {
    return camera_at(0.01 * i, 0.0, 1.2, 0.0, c.pitch_down_deg, c.roll_deg);
  };
  rig.world1 = camera(0);
  std::optional<CraftPose> pose_at_set;
  for (int i = 0; i <= c.expected_set_at + 1; ++i) {
    SCOPED_TRACE(i);
    const bool tracking = i >= c.untracked_first;
    const int tracked = i - c.untracked_first;
    const bool floor = c.floor_visible_from >= 0 && tracked >= c.floor_visible_from;
    // WHEN the results come in
    const CraftPoseUpdate out = rig.slam(camera(i), tracking, 1, 0, floor);
    // THEN no pose before the floor frame is fixed, a pose from then on
    EXPECT_EQ(out.tracking, i >= c.expected_set_at);
    EXPECT_EQ(out.controller.sample.tracking, out.tracking);
    EXPECT_EQ(out.floor_found, i == c.expected_set_at && !c.expected_fallback);
    EXPECT_EQ(out.floor_fallback, i == c.expected_set_at && c.expected_fallback);
    if (i == c.expected_set_at) {
      pose_at_set = out.pose;
      expect_pose_near(out.pose, CraftPose{0.0, 0.0, c.expected_height_m, 0.0}, 0.01);
    } else if (i > c.expected_set_at) {
      // the frame follows the motion: 1 cm forward, height kept
      EXPECT_NEAR(out.pose.x_m - pose_at_set->x_m, 0.01, 1e-3);
      EXPECT_NEAR(out.pose.z_m, pose_at_set->z_m, 1e-3);
    }
  }
  EXPECT_EQ(rig.tracker.floor().has_value(), !c.expected_fallback);
  EXPECT_EQ(rig.tracker.floor_fallback(), c.expected_fallback);
}

INSTANTIATE_TEST_SUITE_P(
    CraftPoseTracker, FloorSearch,
    ::testing::Values(
        FloorCase{"floor_in_view_at_once", 30.0, 0.0, 0, 0, 0, false, 1.2},
        FloorCase{"tilted_floor_found_on_frame_10", 42.0, 8.0, 10, 0, 10, false, 1.2},
        FloorCase{"floor_on_the_last_search_frame", 20.0, -6.0, 29, 0, 29, false, 1.2},
        FloorCase{"no_floor_falls_back_after_30_frames", 30.0, 0.0, -1, 0, 29, true, 0.0},
        FloorCase{"untracked_results_do_not_count", 30.0, 0.0, -1, 5, 34, true, 0.0}),
    [](const auto& info) { return std::string(info.param.name); });

// ---- results that give no pose ------------------------------------------------------------------

struct LostCase {
  const char* name;
  int tracked_before;  ///< tracked results before the lost one (floor in view)
  bool imu;            ///< the APM's IMU telemetry is fresh
  bool expected_sample_tracking;
  bool expected_from_estimator;
};

class LostResult : public ::testing::TestWithParam<LostCase> {};

TEST_P(LostResult, GivenASlamResultThatIsNotTrackingThenTheControllerGetsALostOrBridgedSample) {
  const LostCase c = GetParam();
  Rig rig;
  // GIVEN some tracked results hovering at 1.2 m
  for (int i = 0; i < c.tracked_before; ++i) {
    if (c.imu) rig.imu_until_now();
    rig.slam(rig.world1);
  }
  // WHEN SLAM loses track
  if (c.imu) rig.imu_until_now();
  const CraftPoseUpdate out = rig.slam(rig.world1, false);
  // THEN no pose from the tracker; the controller gets a lost sample repeating the last pose, or
  // the estimator's bridge
  EXPECT_FALSE(out.tracking);
  EXPECT_EQ(out.controller.sample.tracking, c.expected_sample_tracking);
  EXPECT_EQ(out.controller.from_estimator, c.expected_from_estimator);
  EXPECT_EQ(out.controller.velocity_m_per_s.has_value(), c.expected_from_estimator);
  EXPECT_EQ(out.controller.sample.received_us, rig.now_us);
  const CraftPose expected = c.tracked_before > 0 ? CraftPose{0.0, 0.0, 1.2, 0.0} : CraftPose{};
  expect_pose_near(out.controller.sample.pose, expected, 0.02);
}

INSTANTIATE_TEST_SUITE_P(
    CraftPoseTracker, LostResult,
    ::testing::Values(LostCase{"lost_before_any_pose", 0, false, false, false},
                      LostCase{"lost_after_poses_repeats_the_last_pose", 5, false, false, false},
                      LostCase{"lost_with_fresh_imu_is_bridged_by_the_estimate", 5, true, true,
                               true}),
    [](const auto& info) { return std::string(info.param.name); });

// ---- SLAM sessions ------------------------------------------------------------------------------

struct SessionCase {
  const char* name;
  bool new_session;  ///< false: a resumed reconnect (same map, same world frame)
  int lost_results;  ///< results that are not tracking between the two sessions
};

class SlamReconnect : public ::testing::TestWithParam<SessionCase> {};

TEST_P(SlamReconnect, GivenASlamReconnectWhenPosesComeBackThenTheCraftPoseIsContinuous) {
  const SessionCase c = GetParam();
  Rig rig;
  // GIVEN the first session tracking a craft flying forward 2 cm per frame
  auto camera = [](int i) { return camera_at(0.02 * i, 0.01 * i, 1.2, 10.0); };
  rig.world1 = camera(0);
  CraftPose last;
  int i = 0;
  for (; i < 10; ++i) last = rig.slam(camera(i)).pose;
  // (what the first session would have said of the next camera: the floor frame is the tracker's
  // own)
  const Eigen::Isometry3d T_floor_world1 = *rig.tracker.T_floor_world();
  const CraftPose expected_next =
      craft_pose_from(T_floor_world1 * rig.world1.inverse() * camera(i));
  // WHEN the link reconnects (the craft hovers in lost-hold meanwhile); a new session's world frame
  // is its first camera
  const std::uint64_t session = c.new_session ? 2 : 1;
  rig.world2 = camera(i - 1);
  for (int k = 0; k < c.lost_results; ++k) {
    EXPECT_FALSE(rig.slam(camera(i - 1), false, session).controller.sample.tracking);
  }
  const CraftPoseUpdate back = rig.slam(camera(i - 1), true, session);
  const CraftPoseUpdate next = rig.slam(camera(i), true, session);
  // THEN the first pose back is the last one, the next continues the motion, nothing is rejected
  EXPECT_EQ(back.reanchored, c.new_session);
  EXPECT_FALSE(next.reanchored);
  ASSERT_TRUE(back.tracking);
  expect_pose_near(back.pose, last, 1e-9);
  expect_pose_near(next.pose, expected_next, 1e-9);
  EXPECT_NEAR(std::hypot(next.pose.x_m - last.x_m, next.pose.y_m - last.y_m),
              std::hypot(0.02, 0.01), 1e-3);
  EXPECT_EQ(rig.tracker.session(), session);
  EXPECT_EQ(rig.controller.status().rejected_poses, 0u);
}

INSTANTIATE_TEST_SUITE_P(CraftPoseTracker, SlamReconnect,
                         ::testing::Values(SessionCase{"new_session_at_once", true, 0},
                                           SessionCase{"new_session_after_lost_results", true, 5},
                                           SessionCase{"resumed_session_keeps_its_world_frame",
                                                       false, 5}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(CraftPoseTracker, GivenANewSessionWhenItIsNotTrackingYetThenItIsNotAnchored) {
  Rig rig;
  rig.slam(rig.world1);
  // WHEN the second session reports, not tracking THEN the floor frame stays with the first
  EXPECT_FALSE(rig.slam(rig.world1, false, 2).reanchored);
  EXPECT_EQ(rig.tracker.session(), 1u);
  // and a session-1 result that still arrives is used
  EXPECT_TRUE(rig.slam(rig.world1, true, 1).tracking);
}

// ---- declared map corrections -------------------------------------------------------------------

struct CorrectionCase {
  const char* name;
  double jump_m;  ///< SLAM's estimate moves by this along the floor's x in one result
  bool declared;  ///< map_correction_count changes with it
  bool expected_shift;
  std::uint64_t expected_map_resets;  ///< the controller's verdict
  std::uint64_t expected_rejected;
};

class MapCorrection : public ::testing::TestWithParam<CorrectionCase> {};

TEST_P(MapCorrection, GivenTrackingWhenTheMapJumpsThenADeclaredCorrectionShiftsAndIsFlown) {
  const CorrectionCase c = GetParam();
  Rig rig;
  // GIVEN a craft hovering at 1.2 m, tracked
  for (int i = 0; i < 5; ++i) rig.slam(rig.world1);
  ASSERT_TRUE(rig.tracker.pose().has_value());
  const CraftPose before = *rig.tracker.pose();
  // WHEN SLAM's estimate jumps (count 0 -> 1 when declared)
  const CraftPoseUpdate out =
      rig.slam(camera_at(c.jump_m, 0.0, 1.2), true, 1, c.declared ? 1u : 0u);
  // THEN the jump is passed on unchanged with the count; a declared one shifts the estimator
  ASSERT_TRUE(out.tracking);
  EXPECT_TRUE(out.controller.sample.tracking);
  EXPECT_NEAR(out.controller.sample.pose.x_m - before.x_m, c.jump_m, 0.01);
  EXPECT_EQ(out.controller.sample.map_correction_count, c.declared ? 1u : 0u);
  EXPECT_EQ(rig.tracker.map_correction_count(), c.declared ? 1u : 0u);
  EXPECT_EQ(out.map_correction_shift_m.has_value(), c.expected_shift);
  if (out.map_correction_shift_m) {
    EXPECT_NEAR(out.map_correction_shift_m->x(), c.jump_m, 0.01);
  }
  EXPECT_EQ(rig.tracker.estimator().stats().frame_shifts, c.expected_shift ? 1u : 0u);
  // and the controller flies a declared correction, rejects an undeclared jump
  EXPECT_EQ(rig.controller.status().map_resets, c.expected_map_resets);
  EXPECT_EQ(rig.controller.status().rejected_poses, c.expected_rejected);
}

INSTANTIATE_TEST_SUITE_P(
    CraftPoseTracker, MapCorrection,
    ::testing::Values(CorrectionCase{"declared_0_8m_shifts_and_is_flown", 0.8, true, true, 1, 0},
                      CorrectionCase{"undeclared_0_8m_is_passed_and_rejected", 0.8, false, false, 0,
                                     1},
                      CorrectionCase{"declared_0_1m_shifts", 0.1, true, true, 1, 0},
                      CorrectionCase{"undeclared_0_1m_is_motion", 0.1, false, false, 0, 0}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(CraftPoseTracker, GivenACountBeforeTheFirstPoseThenNothingIsShifted) {
  // GIVEN a SLAM that corrected its map before quad-control saw a pose WHEN the first pose comes
  // THEN there is no jump to shift by: the count is taken as it is
  Rig rig;
  const CraftPoseUpdate out = rig.slam(rig.world1, true, 1, 3);
  EXPECT_FALSE(out.map_correction_shift_m.has_value());
  EXPECT_EQ(out.controller.sample.map_correction_count, 3u);
}

// ---- what the controller flies on ---------------------------------------------------------------

struct FeedCase {
  const char* name;
  bool estimator_enabled;
  bool imu;
  bool expected_from_estimator;
};

class ControllerFeedSource : public ::testing::TestWithParam<FeedCase> {};

TEST_P(ControllerFeedSource, GivenTheEstimatorSettingWhenPosesArriveThenTheControllerFliesOnIt) {
  const FeedCase c = GetParam();
  CraftPoseTrackerOptions options;
  options.estimator.enabled = c.estimator_enabled;
  Rig rig(options);
  // GIVEN a hover at 1.2 m, the APM's IMU fresh or silent
  CraftPoseUpdate out;
  for (int i = 0; i < 10; ++i) {
    if (c.imu) rig.imu_until_now();
    out = rig.slam(rig.world1);
  }
  // THEN the controller flies on the estimate (with a velocity) or on the raw pose
  EXPECT_EQ(out.controller.from_estimator, c.expected_from_estimator);
  EXPECT_TRUE(out.controller.sample.tracking);
  EXPECT_EQ(out.controller.velocity_m_per_s.has_value(), c.expected_from_estimator);
  expect_pose_near(out.controller.sample.pose, out.pose, 0.02);
  EXPECT_EQ(rig.tracker.estimates_flown() > 0, c.expected_from_estimator);
  EXPECT_EQ(rig.tracker.last_estimate().has_value(), c.estimator_enabled);
  // and between poses (the command rate) only the estimator has something new
  if (c.imu) rig.imu_until_now();
  EXPECT_EQ(rig.tracker.estimate_feed(rig.now_us + 10'000).has_value(), c.expected_from_estimator);
}

INSTANTIATE_TEST_SUITE_P(CraftPoseTracker, ControllerFeedSource,
                         ::testing::Values(FeedCase{"estimator_with_fresh_imu", true, true, true},
                                           FeedCase{"estimator_without_imu_flies_raw", true, false,
                                                    false},
                                           FeedCase{"estimator_off_flies_raw", false, true, false}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(CraftPoseTracker, InvalidOptionsThrowAtStartUp) {
  CraftPoseTrackerOptions options;
  options.floor_search_frames = 0;
  EXPECT_NE(testing::problem(options), "");
  EXPECT_THROW(CraftPoseTracker{options}, std::invalid_argument);
  options = CraftPoseTrackerOptions{};
  options.mount_pitch_down_deg = 95.0;
  EXPECT_THROW(CraftPoseTracker{options}, std::invalid_argument);
  EXPECT_EQ(testing::problem(CraftPoseTrackerOptions{}), "");
}

TEST(CraftPoseTracker, CraftPoseIsTheCameraCentreAndTheOpticalAxisHeading) {
  for (double yaw : {0.0, 45.0, 170.0, -100.0}) {
    SCOPED_TRACE(yaw);
    const CraftPose p = craft_pose_from(camera_at(1.0, -2.0, 0.7, yaw, 35.0));
    expect_pose_near(p, CraftPose{1.0, -2.0, 0.7, yaw}, 1e-9);
  }
}

TEST(CameraAttitude, TheMountTurnsTheApmAttitudeIntoTheCamerasNedAttitude) {
  // GIVEN the Kinect looking along the body's x axis, pitched 30 deg down (hil/kinect_emulator/
  // poses.py renders the same mount)
  const double a = 30.0 / kDegPerRad;
  ImuSample level;
  const Eigen::Matrix3d R = camera_attitude_ned(level, 30.0).toRotationMatrix();
  // THEN a level craft heading north looks north and 30 deg down, with its image x to the east
  EXPECT_TRUE(R.col(2).isApprox(Eigen::Vector3d(std::cos(a), 0, std::sin(a)), 1e-12));
  EXPECT_TRUE(R.col(0).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
  // AND heading east (yaw 90 deg) it looks east, image x to the south
  ImuSample east;
  east.yaw_rad = 90.0 / kDegPerRad;
  const Eigen::Matrix3d Re = camera_attitude_ned(east, 30.0).toRotationMatrix();
  EXPECT_TRUE(Re.col(2).isApprox(Eigen::Vector3d(0, std::cos(a), std::sin(a)), 1e-12));
  EXPECT_TRUE(Re.col(0).isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
  // AND pitching the nose up by the mount angle levels the optical axis
  ImuSample nose_up;
  nose_up.pitch_rad = a;
  EXPECT_TRUE(camera_attitude_ned(nose_up, 30.0)
                  .toRotationMatrix()
                  .col(2)
                  .isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
}

ImuSample yawed(std::int64_t t_us, double yaw_deg) {
  ImuSample s;
  s.t_us = t_us;
  s.yaw_rad = yaw_deg / kDegPerRad;
  s.pitch_rad = 0.1;  // a craft leaning into a leg: the yaw axis is not the camera's
  return s;
}

TEST(CameraAttitude, AFramesAttitudeIsTheApmAttitudeAtItsCaptureOnTheStationsClock) {
  Rig rig;
  // GIVEN IMU samples but no frame yet THEN the capture clock is unknown: no attitude
  rig.imu_until_now();
  EXPECT_FALSE(rig.tracker.camera_attitude_at(rig.now_us - kLinkDelayUs, 60'000));
  // WHEN frames have set the clock (capture = received - 30 ms here) and the craft then yaws at
  // 30 deg/s, its ATTITUDE sampled every 40 ms (the APM's 25 Hz stream)
  for (int i = 0; i < 3; ++i) rig.slam(camera_at(0, 0, 0.5, 0, 30));
  const std::int64_t t0 = rig.now_us + 5'000;
  const auto yaw_at = [&](std::int64_t t_us) { return 30.0 * (t_us - t0) * 1e-6; };
  for (std::int64_t t = t0; t <= t0 + 120'000; t += 40'000) rig.tracker.on_imu(yawed(t, yaw_at(t)));
  const auto at_capture = [&](std::int64_t local_us) {
    return rig.tracker.camera_attitude_at(local_us - kLinkDelayUs, 60'000);
  };
  const auto truth = [&](std::int64_t local_us) {
    return camera_attitude_ned(yawed(local_us, yaw_at(local_us)), 30.0);
  };
  // THEN a frame captured between two samples gets the attitude at its capture, not the nearer
  // sample's (0.3 deg away)
  const std::int64_t between = t0 + 50'000;
  ASSERT_TRUE(at_capture(between));
  EXPECT_LT(at_capture(between)->angularDistance(truth(between)), 1e-9);
  EXPECT_GT(camera_attitude_ned(yawed(t0 + 40'000, yaw_at(t0 + 40'000)), 30.0)
                .angularDistance(truth(between)),
            0.004);
  // AND a frame captured after the newest sample, before the next has arrived, gets it too
  const std::int64_t ahead = t0 + 150'000;
  ASSERT_TRUE(at_capture(ahead));
  EXPECT_LT(at_capture(ahead)->angularDistance(truth(ahead)), 1e-9);
  // AND a frame captured 100 ms after the newest sample gets none
  EXPECT_FALSE(at_capture(t0 + 220'000));
}

TEST(CameraAttitude, SamplesFurtherApartThanTheWindowGiveTheNearestAsItIs) {
  Rig rig;
  rig.imu_until_now();
  for (int i = 0; i < 3; ++i) rig.slam(camera_at(0, 0, 0.5, 0, 30));
  // GIVEN two ATTITUDE samples 100 ms apart (messages lost between them)
  const std::int64_t t0 = rig.now_us + 200'000;
  rig.tracker.on_imu(yawed(t0, 0.0));
  rig.tracker.on_imu(yawed(t0 + 100'000, 10.0));
  // THEN a frame captured 20 ms after the second gets the second's attitude, not a rate from them
  const auto q = rig.tracker.camera_attitude_at(t0 + 120'000 - kLinkDelayUs, 60'000);
  ASSERT_TRUE(q);
  EXPECT_TRUE(q->isApprox(camera_attitude_ned(yawed(0, 10.0), 30.0), 1e-12));
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
