// Flight state machine and position control: table-driven GIVEN/WHEN/THEN tests, time passed in.
#include "core/flight_controller.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace rgbdquad::quadcontrol {
namespace {

constexpr std::int64_t kStepUs = 20000;  // 50 Hz
constexpr std::int64_t kMsUs = 1000;

class Flight : public ::testing::Test {
 protected:
  FlightController fc{ControlConfig{}};
  std::int64_t now_us = 1'000'000;
  CraftPose pose{0.0, 0.0, 0.3, 0.0};

  StickCommand step(bool tracking = true) {
    now_us += kStepUs;
    fc.on_pose(PoseSample{now_us, tracking, pose});
    return fc.update(now_us);
  }
  void arm_and_wait_gesture(bool tracking = true) {
    ASSERT_EQ(fc.command(now_us, OperatorCommand::kArm), "");
    const std::int64_t until =
        now_us + static_cast<std::int64_t>(fc.config().arm_gesture_ms) * kMsUs;
    while (now_us < until) step(tracking);
  }
  void to_hold() {
    step();
    arm_and_wait_gesture();
    ASSERT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "");
    // The ideal craft follows the height setpoint.
    for (int i = 0; i < 500 && fc.status().state == FlightState::kTakeOff; ++i) {
      step();
      pose.z_m = fc.status().setpoint.z_m;
    }
    ASSERT_EQ(fc.status().state, FlightState::kHold);
  }
};

TEST_F(Flight, CommandTransitionTable) {
  struct Row {
    const char* name;
    FlightState from;
    OperatorCommand cmd;
    bool accepted;
    FlightState to;
  };
  const Row table[] = {
      {"arm from disarmed", FlightState::kDisarmed, OperatorCommand::kArm, true,
       FlightState::kArmed},
      {"takeoff needs armed", FlightState::kDisarmed, OperatorCommand::kTakeOff, false,
       FlightState::kDisarmed},
      {"land when not flying", FlightState::kDisarmed, OperatorCommand::kLand, false,
       FlightState::kDisarmed},
      {"disarm when disarmed", FlightState::kDisarmed, OperatorCommand::kDisarm, false,
       FlightState::kDisarmed},
      {"disarm from armed", FlightState::kArmed, OperatorCommand::kDisarm, true,
       FlightState::kDisarmed},
      {"arm twice", FlightState::kArmed, OperatorCommand::kArm, false, FlightState::kArmed},
      {"takeoff from armed", FlightState::kArmed, OperatorCommand::kTakeOff, true,
       FlightState::kTakeOff},
      {"disarm refused in flight", FlightState::kHold, OperatorCommand::kDisarm, false,
       FlightState::kHold},
      {"takeoff in flight", FlightState::kHold, OperatorCommand::kTakeOff, false,
       FlightState::kHold},
      {"land from hold", FlightState::kHold, OperatorCommand::kLand, true, FlightState::kLand},
      {"land from take-off", FlightState::kTakeOff, OperatorCommand::kLand, true,
       FlightState::kLand},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    FlightController c{ControlConfig{}};
    std::int64_t t = 1'000'000;
    CraftPose p{0, 0, 0.3, 0};
    c.on_pose({t, true, p});
    c.update(t);
    if (row.from != FlightState::kDisarmed) {
      ASSERT_EQ(c.command(t, OperatorCommand::kArm), "");
      for (int i = 0; i < 160; ++i) {  // 3.2 s: past the arming gesture
        t += kStepUs;
        c.on_pose({t, true, p});
        c.update(t);
      }
    }
    if (row.from == FlightState::kTakeOff || row.from == FlightState::kHold) {
      ASSERT_EQ(c.command(t, OperatorCommand::kTakeOff), "");
    }
    if (row.from == FlightState::kHold) {
      for (int i = 0; i < 500 && c.status().state == FlightState::kTakeOff; ++i) {
        t += kStepUs;
        c.on_pose({t, true, p});
        c.update(t);
        p.z_m = c.status().setpoint.z_m;
      }
    }
    ASSERT_EQ(c.status().state, row.from);
    EXPECT_EQ(c.command(t, row.cmd).empty(), row.accepted);
    EXPECT_EQ(c.status().state, row.to);
  }
}

TEST_F(Flight, DisarmedAndArmedOutputsAreSafe) {
  StickCommand s = step();
  EXPECT_FALSE(s.armed);
  EXPECT_EQ(s.throttle_pct, 0.0);
  EXPECT_EQ(s.yaw_pct, 0.0);  // no disarm gesture at start-up
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kArm), "");
  s = step();
  EXPECT_TRUE(s.armed);
  EXPECT_EQ(s.throttle_pct, 0.0);
  EXPECT_EQ(s.roll_pct, 0.0);
}

TEST_F(Flight, ArmingAndDisarmingGestures) {
  step();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kArm), "");
  const std::int64_t armed_at = now_us;
  // GIVEN armed WHEN within arm_gesture_ms THEN throttle 0 + yaw full right, take-off refused
  StickCommand s = step();
  EXPECT_EQ(s.yaw_pct, 100.0);
  EXPECT_EQ(s.throttle_pct, 0.0);
  EXPECT_NE(fc.command(now_us, OperatorCommand::kTakeOff), "");
  while (now_us - armed_at < 2980 * kMsUs) s = step();
  EXPECT_EQ(s.yaw_pct, 100.0);
  // WHEN the gesture time has passed THEN sticks neutral and take-off accepted
  s = step();
  s = step();
  EXPECT_EQ(s.yaw_pct, 0.0);
  // WHEN disarmed THEN yaw full left with the firmware still armed, then released
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kDisarm), "");
  const std::int64_t disarmed_at = now_us;
  s = step();
  EXPECT_TRUE(s.armed);
  EXPECT_EQ(s.yaw_pct, -100.0);
  EXPECT_EQ(s.throttle_pct, 0.0);
  const auto gesture_us = static_cast<std::int64_t>(fc.config().disarm_gesture_ms) * kMsUs;
  while (now_us - disarmed_at < gesture_us - 20 * kMsUs) s = step();
  EXPECT_EQ(s.yaw_pct, -100.0);  // still held just before the end
  while (now_us - disarmed_at < gesture_us + 20 * kMsUs) s = step();
  EXPECT_FALSE(s.armed);
  EXPECT_EQ(s.yaw_pct, 0.0);
}

TEST_F(Flight, TakeoffNeedsTracking) {
  step(false);
  arm_and_wait_gesture(false);
  EXPECT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "takeoff: no tracked pose");
  EXPECT_EQ(fc.status().state, FlightState::kArmed);
}

TEST_F(Flight, TakeoffRampsToHoldHeight) {
  step();
  arm_and_wait_gesture();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "");
  // GIVEN the craft does not climb yet WHEN 1 s passes THEN the setpoint rose 0.5 m and throttle >
  // hover
  StickCommand s;
  for (int i = 0; i < 50; ++i) s = step();
  EXPECT_NEAR(fc.status().setpoint.z_m, 0.3 + 0.5 * (51 * kStepUs) / 1e6, 0.02);
  EXPECT_GT(s.throttle_pct, fc.config().hover_throttle_pct);
  // WHEN the craft follows the setpoint THEN hold once at 1.7 m
  for (int i = 0; i < 500 && fc.status().state == FlightState::kTakeOff; ++i) {
    pose.z_m = fc.status().setpoint.z_m;
    step();
  }
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_NEAR(pose.z_m, 1.7, 0.1);
}

TEST_F(Flight, HoldKeepsTakeoffPositionAndHeading) {
  pose = {1.0, 2.0, 0.3, 45.0};
  to_hold();
  EXPECT_DOUBLE_EQ(fc.status().setpoint.x_m, 1.0);
  EXPECT_DOUBLE_EQ(fc.status().setpoint.y_m, 2.0);
  EXPECT_DOUBLE_EQ(fc.status().setpoint.z_m, 1.7);
  EXPECT_DOUBLE_EQ(fc.status().setpoint.yaw_deg, 45.0);
}

TEST_F(Flight, PositionNeverDrivesYaw) {
  // GIVEN hold, heading 0 (facing +x) WHEN the craft drifts past the setpoint in each direction
  // THEN roll/pitch push it back and the yaw stick stays neutral (no turn towards the goal).
  struct Row {
    const char* name;
    double dx, dy;
    int pitch_sign, roll_sign;
  };
  const Row table[] = {
      {"goal behind", 0.4, 0.0, -1, 0},  // within the 0.5 m pose-jump gate
      {"goal ahead", -0.4, 0.0, +1, 0},
      {"goal to the left", 0.0, -0.4, 0, -1},
      {"goal to the right", 0.0, 0.4, 0, +1},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    FlightController c{ControlConfig{}};
    pose = {0.0, 0.0, 0.3, 0.0};
    std::swap(c, fc);
    to_hold();
    pose.x_m += row.dx;
    pose.y_m += row.dy;
    StickCommand s = step();
    s = step();
    EXPECT_DOUBLE_EQ(s.yaw_pct, 0.0);
    if (row.pitch_sign != 0) {
      EXPECT_EQ(std::signbit(s.pitch_pct), row.pitch_sign < 0);
    } else {
      EXPECT_NEAR(s.pitch_pct, 0.0, 1e-9);
    }
    if (row.roll_sign != 0) {
      EXPECT_EQ(std::signbit(s.roll_pct), row.roll_sign < 0);
    } else {
      EXPECT_NEAR(s.roll_pct, 0.0, 1e-9);
    }
  }
}

TEST_F(Flight, HeadingErrorWrapsTheShortWay) {
  // GIVEN heading 170 deg and setpoint -170 deg THEN it turns 20 deg counter-clockwise (stick left)
  pose = {0.0, 0.0, 0.3, 170.0};
  to_hold();
  ASSERT_EQ(fc.nudge(now_us, 0.0, 0.0, 0.0, 20.0), "");
  EXPECT_NEAR(fc.status().setpoint.yaw_deg, -170.0, 1e-9);
  const StickCommand s = step();
  EXPECT_LT(s.yaw_pct, 0.0);
  EXPECT_NEAR(s.yaw_pct, -0.06 * 20.0, 1e-6);
}

TEST_F(Flight, WaypointTurnsToFaceThenMoves) {
  to_hold();
  // GIVEN a waypoint 2 m behind (-x) WHEN set THEN first turn (yaw stick), position held
  ASSERT_EQ(fc.set_waypoint(now_us, -2.0, 0.0), "");
  EXPECT_EQ(fc.status().state, FlightState::kGoToWaypoint);
  EXPECT_FALSE(fc.status().facing_waypoint);
  StickCommand s = step();
  EXPECT_NE(s.yaw_pct, 0.0);
  EXPECT_NEAR(s.pitch_pct, 0.0, 1e-9);
  EXPECT_DOUBLE_EQ(fc.status().setpoint.x_m, 0.0);
  // WHEN the craft has turned to within tolerance THEN it moves forward towards the goal
  pose.yaw_deg = 175.0;
  s = step();
  EXPECT_TRUE(fc.status().facing_waypoint);
  s = step();
  EXPECT_GT(s.pitch_pct, 0.0);
  // WHEN it arrives (flying there: estimates move a little per frame) THEN hold at the waypoint,
  // heading kept
  for (int i = 1; i <= 19 && fc.status().state == FlightState::kGoToWaypoint; ++i) {
    pose.x_m = -0.1 * i;
    step();
  }
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_DOUBLE_EQ(fc.status().setpoint.x_m, -2.0);
  EXPECT_NEAR(std::abs(fc.status().setpoint.yaw_deg), 180.0, 1e-9);
}

TEST_F(Flight, CloseWaypointMovesWithoutTurning) {
  to_hold();
  ASSERT_EQ(fc.set_waypoint(now_us, -0.2, 0.0), "");
  EXPECT_TRUE(fc.status().facing_waypoint);
  step();
  const StickCommand s = step();
  EXPECT_DOUBLE_EQ(s.yaw_pct, 0.0);
  EXPECT_LT(s.pitch_pct, 0.0);  // backwards
}

TEST_F(Flight, WaypointRejections) {
  EXPECT_NE(fc.set_waypoint(now_us, 1.0, 1.0), "");  // disarmed
  to_hold();
  EXPECT_NE(fc.set_waypoint(now_us, std::nan(""), 1.0), "");
  EXPECT_NE(fc.set_waypoint(now_us, 100.0, 0.0), "");
  EXPECT_EQ(fc.status().state, FlightState::kHold);
}

TEST_F(Flight, TrackingLostHoldsNeutralThenLands) {
  to_hold();
  const double hover = fc.config().hover_throttle_pct;
  // WHEN SLAM reports lost for longer than pose_timeout_ms THEN lost-hold with neutral sticks
  StickCommand s;
  std::int64_t lost_at = now_us;
  for (int i = 0; i < 20; ++i) s = step(false);
  EXPECT_EQ(fc.status().state, FlightState::kLostHold);
  EXPECT_EQ(s.roll_pct, 0.0);
  EXPECT_EQ(s.pitch_pct, 0.0);
  EXPECT_EQ(s.yaw_pct, 0.0);
  EXPECT_NEAR(s.throttle_pct, hover, 0.5);  // + the (here tiny) learned offset
  // AND after lost_hold_ms without tracking THEN land
  while (fc.status().state == FlightState::kLostHold) s = step(false);
  EXPECT_EQ(fc.status().state, FlightState::kLand);
  EXPECT_NEAR(static_cast<double>(now_us - lost_at) / kMsUs, 2000.0 + kStepUs / kMsUs,
              2.0 * kStepUs / kMsUs);
}

TEST_F(Flight, TrackingBackResumesHold) {
  to_hold();
  for (int i = 0; i < 5; ++i) step(false);
  EXPECT_EQ(fc.status().state, FlightState::kLostHold);
  step(true);
  EXPECT_EQ(fc.status().state, FlightState::kHold);
}

TEST_F(Flight, TrackingBackDuringTakeoffClimbsOn) {
  step();
  arm_and_wait_gesture();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "");
  for (int i = 0; i < 40; ++i) {
    pose.z_m = fc.status().setpoint.z_m;
    step();
  }
  const double reached_m = fc.status().setpoint.z_m;
  ASSERT_LT(reached_m, 1.0);
  // GIVEN tracking is lost half-way up WHEN it comes back THEN the climb goes on from there
  for (int i = 0; i < 5; ++i) step(false);
  ASSERT_EQ(fc.status().state, FlightState::kLostHold);
  step(true);
  EXPECT_EQ(fc.status().state, FlightState::kTakeOff);
  EXPECT_NEAR(fc.status().setpoint.z_m, reached_m, 0.02);
  for (int i = 0; i < 500 && fc.status().state == FlightState::kTakeOff; ++i) {
    pose.z_m = fc.status().setpoint.z_m;
    step();
  }
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_NEAR(pose.z_m, 1.7, 0.1);
}

// Commands go out at 50 Hz, poses come at the camera's rate: the PIDs run once per pose, so the
// command between two poses is held (no derivative spike per frame, no zeros in between).
TEST_F(Flight, PidsRunOncePerPoseSample) {
  to_hold();
  pose.x_m = -0.2;  // 20 cm behind: pitch forward
  now_us += kStepUs;
  fc.on_pose(PoseSample{now_us, true, pose});
  const StickCommand first = fc.update(now_us);
  ASSERT_NE(first.pitch_pct, 0.0);
  for (int i = 0; i < 2; ++i) {  // two more ticks, no new pose (15 fps camera)
    now_us += kStepUs;
    const StickCommand again = fc.update(now_us);
    EXPECT_EQ(again.pitch_pct, first.pitch_pct);
    EXPECT_EQ(again.throttle_pct, first.throttle_pct);
  }
  // The next pose (unchanged position) gives the derivative over the pose interval (60 ms),
  // not over one 20 ms tick: the D term relaxes towards P alone instead of spiking.
  now_us += kStepUs;
  fc.on_pose(PoseSample{now_us, true, pose});
  const StickCommand next = fc.update(now_us);
  EXPECT_GT(next.pitch_pct, 0.0);
  EXPECT_LT(std::abs(next.pitch_pct), 20.0);
}

TEST_F(Flight, LostHoldHoversWithTheLearnedThrottleAndKeepsIt) {
  to_hold();
  // GIVEN the craft sat 10 cm low for 10 s (heavier than the feed-forward assumes)
  pose.z_m = 1.6;
  for (int i = 0; i < 500; ++i) step();
  const double hover = fc.config().hover_throttle_pct;
  // WHEN tracking is lost THEN lost-hold hovers at the feed-forward plus the learned offset
  StickCommand s;
  for (int i = 0; i < 20; ++i) s = step(false);
  ASSERT_EQ(fc.status().state, FlightState::kLostHold);
  const double learned = s.throttle_pct - hover;
  EXPECT_GT(learned, 5.0);
  // AND when tracking is back at the hold height the offset is still there (not reset)
  pose.z_m = 1.7;
  s = step(true);
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_NEAR(s.throttle_pct, hover + learned, 1.0);
}

TEST_F(Flight, PoseJumpIsRejectedUntilTheEstimateComesBackElseLandsBlind) {
  to_hold();
  // GIVEN SLAM jumps 1.5 m down (a false loop closure) WHEN it stays there THEN never flown on:
  // lost-hold (hover), then a blind landing - not a full-throttle climb
  pose.z_m = 0.2;
  StickCommand s;
  for (int i = 0; i < 20; ++i) s = step();
  EXPECT_EQ(fc.status().state, FlightState::kLostHold);
  EXPECT_GE(fc.status().rejected_poses, 15u);
  EXPECT_LE(s.throttle_pct, fc.config().hover_throttle_pct + 1.0);
  // AND WHEN the estimate comes back near the last accepted pose THEN hold again
  pose.z_m = 1.68;
  step();
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  // AND a jump that persists ends in the blind landing: handed over to the craft's failsafe,
  // whatever the (wrong) estimate says
  pose.z_m = 0.2;
  while (fc.status().state != FlightState::kLand) s = step();
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(step().hand_over_to_failsafe);
}

TEST_F(Flight, TrackingBackDuringGoToGoesOnToTheWaypoint) {
  to_hold();
  ASSERT_EQ(fc.set_waypoint(now_us, 0.0, 2.0), "");  // to the left: turn first
  step();
  for (int i = 0; i < 5; ++i) step(false);
  ASSERT_EQ(fc.status().state, FlightState::kLostHold);
  step(true);
  EXPECT_EQ(fc.status().state, FlightState::kGoToWaypoint);
  ASSERT_TRUE(fc.status().waypoint.has_value());
  EXPECT_DOUBLE_EQ(fc.status().waypoint->y_m, 2.0);
}

TEST_F(Flight, StalePoseCountsAsLost) {
  to_hold();
  // No pose arrives for more than pose_timeout_ms.
  now_us += 301 * kMsUs;
  fc.update(now_us);
  EXPECT_EQ(fc.status().state, FlightState::kLostHold);
}

TEST_F(Flight, NonFinitePoseCountsAsLost) {
  to_hold();
  pose.x_m = std::numeric_limits<double>::quiet_NaN();
  const StickCommand s = step(true);
  EXPECT_EQ(fc.status().state, FlightState::kLostHold);
  EXPECT_TRUE(std::isfinite(s.roll_pct));
}

TEST_F(Flight, TrackedLandingSinksTheHeightSetpointThenMotorsStop) {
  to_hold();
  step();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  const double max_sink_per_step = fc.config().land_descent_rate_m_per_s * kStepUs / 1e6 + 1e-9;
  double previous = fc.status().setpoint.z_m;
  // GIVEN the craft follows the height setpoint WHEN landing THEN the setpoint sinks at the descent
  // rate, never faster, and the craft stays armed until near the ground
  StickCommand s;
  int steps = 0;
  while (fc.status().state == FlightState::kLand && steps < 2000) {
    s = step();
    if (fc.status().state != FlightState::kLand) break;
    EXPECT_LE(previous - fc.status().setpoint.z_m, max_sink_per_step);
    EXPECT_LE(fc.status().setpoint.z_m, previous + 1e-12);
    EXPECT_TRUE(s.armed);
    previous = fc.status().setpoint.z_m;
    pose.z_m = fc.status().setpoint.z_m;
    ++steps;
  }
  // 1.7 m at 0.3 m/s: ~5.2 s to the motor-stop height, then land_ground_settle_ms there
  EXPECT_NEAR(
      steps * kStepUs / 1e6,
      (1.7 - fc.config().motor_stop_height_m) / 0.3 + fc.config().land_ground_settle_ms / 1e3, 0.1);
  // THEN the motors stop once the craft is near the ground, with the disarm gesture
  EXPECT_EQ(fc.status().state, FlightState::kDisarmed);
  EXPECT_EQ(s.throttle_pct, 0.0);
  EXPECT_EQ(s.yaw_pct, -100.0);
  EXPECT_LE(pose.z_m, fc.config().motor_stop_height_m + 0.02);
}

TEST_F(Flight, TrackedLandingOnALowFloorStopsAfterFloorHold) {
  to_hold();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  // GIVEN the camera cannot get below 0.25 m (landing gear higher than motor_stop_height_m)
  while (fc.status().state == FlightState::kLand) {
    step();
    pose.z_m = std::max(0.25, fc.status().setpoint.z_m);
  }
  // THEN it still stops: land_floor_hold_ms after the setpoint reached the stop height
  EXPECT_EQ(fc.status().state, FlightState::kDisarmed);
}

TEST_F(Flight, LandingAbandonsTheWaypointAndLandsInPlace) {
  to_hold();
  ASSERT_EQ(fc.set_waypoint(now_us, 0.2, 0.0), "");  // close: moves at once
  pose.x_m = 0.1;
  step();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  EXPECT_FALSE(fc.status().waypoint.has_value());
  EXPECT_DOUBLE_EQ(fc.status().setpoint.x_m, 0.1);
  step();
  const StickCommand s = step();
  EXPECT_NEAR(s.pitch_pct, 0.0, 1e-9);
}

TEST_F(Flight, BlindLandingHandsOverToTheFailsafeThenDisarmsTheFirmware) {
  to_hold();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  const std::int64_t start = now_us;
  // GIVEN no pose WHEN landing THEN no command is sent (the firmware's failsafe hands the craft
  // to the APM's LAND), and it stays so even if a pose comes back (the firmware is latched)
  StickCommand s = step(false);
  EXPECT_TRUE(s.hand_over_to_failsafe);
  s = step(true);
  EXPECT_TRUE(s.hand_over_to_failsafe);
  EXPECT_EQ(fc.status().state, FlightState::kLand);
  while (fc.status().state == FlightState::kLand) s = step(false);
  // THEN after failsafe_landing_ms: disarmed, commanding arm=0 (clears the firmware's latch), no
  // disarm gesture (the APM disarmed itself after its LAND)
  const double elapsed_ms = static_cast<double>(now_us - start) / 1e3;
  EXPECT_NEAR(elapsed_ms, fc.config().failsafe_landing_ms + kStepUs / 1e3, 2.0 * kStepUs / 1e3);
  EXPECT_EQ(fc.status().state, FlightState::kDisarmed);
  EXPECT_FALSE(s.hand_over_to_failsafe);
  EXPECT_FALSE(s.armed);
  s = step(true);
  EXPECT_FALSE(s.armed);
  EXPECT_EQ(s.yaw_pct, 0.0);
}

TEST_F(Flight, ManualNudgeMovesSetpointInBodyFrame) {
  pose = {0.0, 0.0, 0.3, 90.0};  // facing +y
  to_hold();
  ASSERT_EQ(fc.nudge(now_us, 0.1, 0.0, 0.0, 0.0), "");
  EXPECT_NEAR(fc.status().setpoint.x_m, 0.0, 1e-9);
  EXPECT_NEAR(fc.status().setpoint.y_m, 0.1, 1e-9);
  ASSERT_EQ(fc.nudge(now_us, 0.0, 0.1, 0.1, 0.0), "");  // left of +y is -x
  EXPECT_NEAR(fc.status().setpoint.x_m, -0.1, 1e-9);
  EXPECT_NEAR(fc.status().setpoint.z_m, 1.8, 1e-9);
  EXPECT_NE(fc.nudge(now_us, std::nan(""), 0.0, 0.0, 0.0), "");
}

// Declared map corrections (PX4 EKF2 reset-counter style): a jump that arrives with a
// changed map_correction_count is SLAM correcting its map, flown as a re-anchor; the same jump
// without a count change is a SLAM failure, rejected as before.
struct CorrectionCase {
  const char* name;
  double jump_x_m;           ///< the pose moves by this in one sample
  bool declared;             ///< map_correction_count changes with it
  FlightState expected;      ///< state 10 samples later (the pose stays corrected)
  std::uint64_t map_resets;  ///< expected status
  std::uint64_t refused;     ///< expected refused_map_corrections
};

class DeclaredCorrection : public Flight, public ::testing::WithParamInterface<CorrectionCase> {};

TEST_P(DeclaredCorrection, GivenHoldWhenTheMapJumpsThenOnlyADeclaredBoundedCorrectionIsFlown) {
  const CorrectionCase c = GetParam();
  to_hold();
  const CraftPose setpoint = fc.status().setpoint;
  // WHEN the pose jumps by jump_x_m (count 0 -> 1 if declared) and stays there
  std::uint32_t count = 0;
  if (c.declared) count = 1;
  pose.x_m += c.jump_x_m;
  StickCommand s;
  for (int i = 0; i < 10; ++i) {
    now_us += kStepUs;
    fc.on_pose(PoseSample{now_us, true, pose, count});
    s = fc.update(now_us);
  }
  // THEN
  EXPECT_EQ(fc.status().state, c.expected) << fc.status().last_event;
  EXPECT_EQ(fc.status().map_resets, c.map_resets);
  EXPECT_EQ(fc.status().refused_map_corrections, c.refused);
  if (c.expected == FlightState::kHold) {
    // the setpoint stays in the world frame: the craft is flown back to it (behind it: pitch back)
    EXPECT_DOUBLE_EQ(fc.status().setpoint.x_m, setpoint.x_m);
    EXPECT_LT(s.pitch_pct, 0.0);
    EXPECT_EQ(fc.status().rejected_poses, 0u);
  } else {
    EXPECT_GE(fc.status().rejected_poses, 1u);
  }
}

INSTANTIATE_TEST_SUITE_P(
    MapCorrection, DeclaredCorrection,
    ::testing::Values(
        CorrectionCase{"declared_0_7m_flown", 0.7, true, FlightState::kHold, 1, 0},
        CorrectionCase{"undeclared_0_7m_rejected", 0.7, false, FlightState::kLostHold, 0, 0},
        CorrectionCase{"declared_2_0m_refused", 2.0, true, FlightState::kLostHold, 0, 1},
        CorrectionCase{"declared_0_1m_flown", 0.1, true, FlightState::kHold, 1, 0}),
    [](const auto& info) { return std::string(info.param.name); });

TEST_F(Flight, DeclaredCorrectionDoesNotKickTheDerivative) {
  // GIVEN two identical holds; WHEN the same 0.3 m jump (inside max_pose_jump_m) arrives once
  // undeclared and once declared THEN the declared one commands no derivative spike: a smaller
  // pitch than the undeclared one, which differentiates the jump over one pose interval.
  struct Rig : Flight {
    void TestBody() override {}
    double pitch_after_jump(bool declared) {
      to_hold();
      pose.x_m += 0.3;
      now_us += kStepUs;
      fc.on_pose(PoseSample{now_us, true, pose, declared ? 1u : 0u});
      return fc.update(now_us).pitch_pct;
    }
  };
  const double undeclared = Rig{}.pitch_after_jump(false);
  const double declared = Rig{}.pitch_after_jump(true);
  EXPECT_LT(declared, 0.0);
  EXPECT_LT(std::abs(declared), std::abs(undeclared));
}

TEST_F(Flight, PositionLawIsSelectableAndTheThesisPidIsUnchanged) {
  // GIVEN the same hold 0.2 m behind the setpoint, flown once with each law
  struct Row {
    const char* name;
    PositionLaw law;
    double expected_pitch_pct;
  };
  // The thesis PID: P alone, 0.015 %/mm x 200 mm (D on a zero velocity, no ki in Table 3.1). The
  // cascade: 1/s x 0.2 m -> 0.2 m/s asked, 3.5/s -> 0.7 m/s^2, atan(0.7 / g) of 45 deg.
  const double cascade_pct = std::atan(0.7 / 9.80665) * 57.29577951308232 / 45.0 * 100.0;
  const Row table[] = {{"pid (Table 3.1)", PositionLaw::kPid, 0.015 * 200.0},
                       {"cascade", PositionLaw::kCascade, cascade_pct}};
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    ControlConfig config;
    config.position_law = row.law;
    config.cascade.velocity_ki_per_s2 = 0.0;  // compare the proportional paths alone
    FlightController c{config};
    pose = {0.0, 0.0, 0.3, 0.0};
    std::swap(c, fc);
    to_hold();
    // WHEN the craft sits 0.2 m behind the setpoint at rest (the estimator's velocity: 0)
    pose.x_m -= 0.2;
    StickCommand s;
    for (int i = 0; i < 3; ++i) {
      now_us += kStepUs;
      fc.on_pose(PoseSample{now_us, true, pose}, Velocity3{0.0, 0.0, 0.0});
      s = fc.update(now_us);
    }
    // THEN each law asks for its own lean forward
    EXPECT_NEAR(s.pitch_pct, row.expected_pitch_pct, 1e-6);
    EXPECT_NEAR(s.roll_pct, 0.0, 1e-9);
  }
}

TEST_F(Flight, ManoeuvreRequestsAreCheckedAgainstTheirBounds) {
  to_hold();
  struct Row {
    const char* name;
    ManoeuvreRequest request;
    const char* refusal;  // "" = accepted
  };
  constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  const Row table[] = {
      {"nothing", {}, "manoeuvre: nothing to do"},
      {"NaN", {kNan, 0, 0, 1.0, 0}, "manoeuvre: non-finite value"},
      {"too far", {3.0, 0, 0, 1.0, 0}, "manoeuvre: move longer than max_manoeuvre_distance_m"},
      {"too fast",
       {1.0, 0, 0, 2.0, 0},
       "manoeuvre: speed_m_per_s must be in (0, max_manoeuvre_speed_m_per_s]"},
      {"move without a speed",
       {1.0, 0, 0, 0.0, 0},
       "manoeuvre: speed_m_per_s must be in (0, max_manoeuvre_speed_m_per_s]"},
      {"turn too fast",
       {0, 0, 90.0, 0, 120.0},
       "manoeuvre: yaw_rate_deg_per_s must be in (0, max_manoeuvre_yaw_rate_deg_per_s]"},
      {"two turns and more",
       {0, 0, 400.0, 0, 60.0},
       "manoeuvre: turn larger than max_manoeuvre_turn_deg"},
      {"a half turn at 60 deg/s", {0, 0, 180.0, 0, 60.0}, ""},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    EXPECT_EQ(fc.manoeuvre(now_us, row.request), row.refusal);
  }
  // A second one while the first runs is refused.
  EXPECT_EQ(fc.manoeuvre(now_us, {0, 0, 90.0, 0, 60.0}), "manoeuvre: one is in progress");
}

TEST_F(Flight, ManoeuvreEndingOutsideTheEnvelopeIsRefusedNotShortened) {
  // GIVEN a 2 m envelope around home and the setpoint 0.5 m ahead of home
  ControlConfig config;
  config.max_distance_from_home_m = 2.0;
  config.max_manoeuvre_distance_m = 2.0;
  FlightController c{config};
  std::swap(c, fc);
  to_hold();
  ASSERT_EQ(fc.nudge(now_us, 0.5, 0.0, 0.0, 0.0), "");
  step();
  // WHEN a 2 m dash forward is asked THEN it is refused (it would end 2.5 m out), and one that
  // ends inside is accepted
  EXPECT_EQ(fc.manoeuvre(now_us, {2.0, 0.0, 0.0, 1.0, 0.0}),
            "manoeuvre: end point outside the flight envelope");
  EXPECT_FALSE(fc.status().manoeuvre_active);
  EXPECT_EQ(fc.manoeuvre(now_us, {-2.0, 0.0, 0.0, 1.0, 0.0}), "");
}

TEST_F(Flight, DashMovesTheSetpointOnARampedProfileAndFeedsItsSpeedForward) {
  to_hold();
  const double x0 = fc.status().setpoint.x_m;
  // GIVEN hold facing +x WHEN a 2 m dash forward at 1 m/s is asked (1 m/s^2 ramps: 1 s up,
  // 1 s at 1 m/s, 1 s down, 3 s in all)
  ASSERT_EQ(fc.manoeuvre(now_us, {2.0, 0.0, 0.0, 1.0, 0.0}), "");
  const std::int64_t start = now_us;
  std::optional<double> x_at_half_s, x_at_1_5_s;
  while (fc.status().manoeuvre_active && now_us - start < 5'000'000) {
    step();
    pose.x_m = fc.status().setpoint.x_m;  // the ideal craft follows
    const std::int64_t t = now_us - start;
    if (!x_at_half_s && t >= 500'000) x_at_half_s = fc.status().setpoint.x_m - x0;
    if (!x_at_1_5_s && t >= 1'500'000) x_at_1_5_s = fc.status().setpoint.x_m - x0;
  }
  // THEN the setpoint follows 0.5 a t^2 on the ramp and 1 m/s in the middle, ends on the goal
  // within the 3 s profile, and the craft is back in plain hold
  ASSERT_TRUE(x_at_half_s && x_at_1_5_s);
  EXPECT_NEAR(*x_at_half_s, 0.125, 0.021);  // one 20 ms step of slack
  EXPECT_NEAR(*x_at_1_5_s, 1.0, 0.021);
  EXPECT_NEAR(now_us - start, 3'000'000, kStepUs);
  EXPECT_NEAR(fc.status().setpoint.x_m - x0, 2.0, 1e-9);
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_EQ(fc.status().manoeuvres_done, 1u);
}

TEST_F(Flight, DashFeedForwardLeansIntoTheMoveBeforeAnErrorBuildsUp) {
  to_hold();
  ASSERT_EQ(fc.manoeuvre(now_us, {1.0, 0.0, 0.0, 1.0, 0.0}), "");
  // WHEN the craft follows the setpoint exactly (no error) at its speed, through the estimator's
  // velocity, in the middle of the ramp-up
  StickCommand s;
  double last_x = pose.x_m;
  for (int i = 0; i < 25; ++i) {
    now_us += kStepUs;
    fc.update(now_us);
    const double v = (fc.status().setpoint.x_m - last_x) / (kStepUs / 1e6);
    last_x = fc.status().setpoint.x_m;
    pose.x_m = fc.status().setpoint.x_m;
    fc.on_pose(PoseSample{now_us, true, pose}, Velocity3{v, 0.0, 0.0});
    s = fc.update(now_us);
  }
  // THEN the cascade asks for (almost) no lean: the move is the feed-forward's, not an error's
  EXPECT_NEAR(s.pitch_pct, 0.0, 1.0);
}

TEST_F(Flight, TurnFeedsTheRateForwardAsYawStick) {
  to_hold();
  // GIVEN a half turn counter-clockwise at 60 deg/s (ramped at 120 deg/s^2: 0.5 s up)
  ASSERT_EQ(fc.manoeuvre(now_us, {0.0, 0.0, 180.0, 0.0, 60.0}), "");
  const std::int64_t start = now_us;
  StickCommand mid;
  while (fc.status().manoeuvre_active && now_us - start < 10'000'000) {
    const StickCommand s = step();
    pose.yaw_deg = fc.status().setpoint.yaw_deg;  // the ideal craft follows
    if (now_us - start >= 1'500'000 && now_us - start < 1'500'000 + kStepUs) mid = s;
  }
  // THEN at full rate the stick is the APM's stick for 60 deg/s to the left (of 202.5 at full
  // stick), minus the yaw PID's derivative on the measured rate; 180 deg take 3.5 s
  const double ff_pct = -60.0 / 202.5 * 100.0;
  EXPECT_NEAR(mid.yaw_pct, ff_pct, 2.0);
  EXPECT_LT(mid.yaw_pct, -fc.config().yaw.output_limit_pct + 2.0);
  EXPECT_NEAR(now_us - start, 3'500'000, kStepUs);
  EXPECT_NEAR(std::abs(fc.status().setpoint.yaw_deg), 180.0, 1e-6);
}

TEST_F(Flight, LandingEndsAManoeuvreWhereItIs) {
  to_hold();
  ASSERT_EQ(fc.manoeuvre(now_us, {2.0, 0.0, 0.0, 1.0, 0.0}), "");
  for (int i = 0; i < 50; ++i) step();  // 1 s in: the setpoint is ~0.5 m along
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  EXPECT_FALSE(fc.status().manoeuvre_active);
  const double x = fc.status().setpoint.x_m;
  for (int i = 0; i < 50; ++i) step();
  EXPECT_DOUBLE_EQ(fc.status().setpoint.x_m, x);
}

TEST(FlightControllerConfig, InvalidConfigThrowsAtStartUp) {
  ControlConfig c;
  c.hover_throttle_pct = -1.0;
  EXPECT_THROW(FlightController{c}, std::invalid_argument);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
