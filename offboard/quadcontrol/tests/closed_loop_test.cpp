// Closed loop: the FlightController with Table 3.1 gains flying a simple point-mass craft model
// (stabilise-mode ArduCopter: stick -> tilt angle, throttle -> vertical thrust, yaw stick -> yaw
// rate, linear drag). Not a flight-dynamics validation: it checks that the gains, signs, units and
// state machine fit together (take-off reaches hold, a waypoint behind is reached by turning then
// flying, landing stops the motors) with time passed in, at the 50 Hz command rate.
#include <gtest/gtest.h>

#include <cmath>

#include "core/flight_controller.hpp"
#include "core/geometry.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr double kG = 9.81;
constexpr double kAngleMaxDeg = 45.0;      // ArduCopter ANGLE_MAX default: full stick = 45 deg
constexpr double kYawRateMaxDegS = 200.0;  // ~ full yaw stick in stabilise
constexpr double kDragPerS = 0.5;          // linear drag of a small quad, 1/s
constexpr std::int64_t kStepUs = 20000;

struct Craft {
  CraftPose p{0.0, 0.0, 0.3, 0.0};
  double vx = 0, vy = 0, vz = 0;
  void step(const StickCommand& s, double hover_pct, double dt) {
    if (!s.armed || s.throttle_pct <= 0.0) {  // motors off: on the ground
      vx = vy = vz = 0;
      return;
    }
    const double yaw = p.yaw_deg / kDegPerRad;
    const double a_fwd = kG * std::tan(s.pitch_pct / 100.0 * kAngleMaxDeg / kDegPerRad);
    const double a_right = kG * std::tan(s.roll_pct / 100.0 * kAngleMaxDeg / kDegPerRad);
    // forward = (cos yaw, sin yaw), right = (sin yaw, -cos yaw)
    vx += (a_fwd * std::cos(yaw) + a_right * std::sin(yaw) - kDragPerS * vx) * dt;
    vy += (a_fwd * std::sin(yaw) - a_right * std::cos(yaw) - kDragPerS * vy) * dt;
    vz += (kG * (s.throttle_pct / hover_pct - 1.0) - kDragPerS * vz) * dt;
    p.x_m += vx * dt;
    p.y_m += vy * dt;
    p.z_m = std::max(0.0, p.z_m + vz * dt);
    if (p.z_m == 0.0 && vz < 0) vz = 0;
    p.yaw_deg =
        wrap_deg(p.yaw_deg - s.yaw_pct / 100.0 * kYawRateMaxDegS * dt);  // + stick = clockwise
  }
};

class ClosedLoop : public ::testing::Test {
 protected:
  FlightController fc{ControlConfig{}};
  Craft craft;
  std::int64_t now_us = 0;
  double max_tilt_pct = 0.0;

  void run_s(double seconds) {
    const int steps = static_cast<int>(seconds * 1e6 / kStepUs);
    for (int i = 0; i < steps; ++i) {
      now_us += kStepUs;
      fc.on_pose(PoseSample{now_us, true, craft.p});
      const StickCommand s = fc.update(now_us);
      max_tilt_pct = std::max({max_tilt_pct, std::abs(s.roll_pct), std::abs(s.pitch_pct)});
      craft.step(s, fc.config().hover_throttle_pct, kStepUs / 1e6);
    }
  }
};

TEST_F(ClosedLoop, TakeoffHoldWaypointBehindLand) {
  run_s(0.1);
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kArm), "");
  run_s(fc.config().arm_gesture_ms / 1000.0 + 0.1);  // ArduCopter's arming gesture
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "");
  // GIVEN take-off WHEN 15 s pass THEN holding at 1.7 m, within 10 cm, over the take-off point
  run_s(15.0);
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_NEAR(craft.p.z_m, 1.7, 0.1);
  EXPECT_NEAR(craft.p.x_m, 0.0, 0.1);
  // WHEN a waypoint 2 m behind is set THEN the craft turns to face it, flies there, holds
  ASSERT_EQ(fc.set_waypoint(now_us, -2.0, 0.0), "");
  run_s(30.0);
  EXPECT_EQ(fc.status().state, FlightState::kHold);
  EXPECT_NEAR(craft.p.x_m, -2.0, 0.2);
  EXPECT_NEAR(craft.p.y_m, 0.0, 0.2);
  EXPECT_NEAR(std::abs(craft.p.yaw_deg), 180.0, 10.0);
  EXPECT_NEAR(craft.p.z_m, 1.7, 0.15);
  EXPECT_LE(max_tilt_pct, fc.config().pitch.output_limit_pct + 1e-9);
  // WHEN land THEN the motors stop near the ground
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  run_s(30.0);
  EXPECT_EQ(fc.status().state, FlightState::kDisarmed);
  EXPECT_LT(craft.p.z_m, 0.2);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
