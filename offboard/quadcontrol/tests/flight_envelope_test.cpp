// The flight envelope as one contract: every path that writes a setpoint
// (manual steps, waypoints, take-off, landing) with NaN, inf, huge and negative values.
// Table-driven, GIVEN/WHEN/THEN, time passed in, seeded.
#include "core/flight_envelope.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/flight_controller.hpp"
#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kHuge = 1e308;
constexpr double kMax = std::numeric_limits<double>::max();
constexpr std::int64_t kStepUs = 20000;  // 50 Hz
constexpr std::int64_t kMsUs = 1000;

// ---- FlightEnvelope alone ----

TEST(FlightEnvelope, ContainTable) {
  struct Row {
    const char* name;
    SetpointPosition wanted;
    SetpointKind kind;
    bool accepted;
    SetpointPosition expected;  // when accepted
    bool clamped;
  };
  // GIVEN home at (1, 1), 5 m fence, heights [0.3, 3] m
  const Row table[] = {
      {"inside", {2, 2, 1.7}, SetpointKind::kHold, true, {2, 2, 1.7}, false},
      {"on the fence", {6, 1, 1.7}, SetpointKind::kHold, true, {6, 1, 1.7}, false},
      {"50 m east", {51, 1, 1.7}, SetpointKind::kHold, true, {6, 1, 1.7}, true},
      {"50 m south-west",
       {1 - 30, 1 - 40, 1.7},
       SetpointKind::kHold,
       true,
       {1 - 3, 1 - 4, 1.7},
       true},
      {"huge x", {kHuge, 1, 1.7}, SetpointKind::kHold, true, {6, 1, 1.7}, true},
      {"max x and y (hypot overflows)",
       {kMax, kMax, 1.7},
       SetpointKind::kHold,
       true,
       {1 + 5 / std::sqrt(2.0), 1 + 5 / std::sqrt(2.0), 1.7},
       true},
      {"huge negative x", {-kHuge, 1, 1.7}, SetpointKind::kHold, true, {-4, 1, 1.7}, true},
      {"101 m up", {1, 1, 101}, SetpointKind::kHold, true, {1, 1, 3}, true},
      {"huge height", {1, 1, kHuge}, SetpointKind::kHold, true, {1, 1, 3}, true},
      {"negative height", {1, 1, -5}, SetpointKind::kHold, true, {1, 1, 0.3}, true},
      {"take-off from the floor", {1, 1, 0.05}, SetpointKind::kTakeOff, true, {1, 1, 0.05}, false},
      {"take-off below the floor", {1, 1, -0.2}, SetpointKind::kTakeOff, true, {1, 1, 0}, true},
      {"landing outside the fence stays",
       {30, 1, 1.0},
       SetpointKind::kLanding,
       true,
       {30, 1, 1.0},
       false},
      {"landing above the ceiling", {30, 1, 9.0}, SetpointKind::kLanding, true, {30, 1, 3.0}, true},
      {"NaN x", {kNaN, 1, 1.7}, SetpointKind::kHold, false, {}, false},
      {"inf y", {1, kInf, 1.7}, SetpointKind::kHold, false, {}, false},
      {"-inf z", {1, 1, -kInf}, SetpointKind::kHold, false, {}, false},
      {"NaN landing", {1, 1, kNaN}, SetpointKind::kLanding, false, {}, false},
      {"inf take-off", {kInf, 1, 0.1}, SetpointKind::kTakeOff, false, {}, false},
  };
  FlightEnvelope envelope(EnvelopeLimits{5.0, 0.3, 3.0});
  envelope.set_home(1.0, 1.0);
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    // WHEN the setpoint is contained
    const auto c = envelope.contain(row.wanted, row.kind);
    // THEN it is refused or lands where expected
    ASSERT_EQ(c.has_value(), row.accepted);
    if (!c) continue;
    EXPECT_NEAR(c->position.x_m, row.expected.x_m, 1e-9);
    EXPECT_NEAR(c->position.y_m, row.expected.y_m, 1e-9);
    EXPECT_NEAR(c->position.z_m, row.expected.z_m, 1e-9);
    EXPECT_EQ(c->clamped, row.clamped);
  }
}

TEST(FlightEnvelope, WaypointTable) {
  struct Row {
    const char* name;
    double x_m, y_m;
    bool accepted;
  };
  const Row table[] = {
      {"inside", 2, 0, true},
      {"on the fence (3,4)", 3, 4, true},
      {"negative inside", -3, -3, true},
      {"just outside", 5.01, 0, false},
      {"negative outside", -50, 0, false},
      {"huge", kHuge, 0, false},
      {"max both", kMax, kMax, false},
      {"-huge", 0, -kHuge, false},
      {"NaN", kNaN, 0, false},
      {"inf", 0, kInf, false},
      {"-inf", -kInf, 0, false},
  };
  FlightEnvelope envelope(EnvelopeLimits{5.0, 0.3, 3.0});
  EXPECT_NE(envelope.check_waypoint(1.0, 0.0), "");  // GIVEN no home THEN nothing is flown
  envelope.set_home(0.0, 0.0);
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    EXPECT_EQ(envelope.check_waypoint(row.x_m, row.y_m).empty(), row.accepted);
  }
}

// ---- the controller: each API path ----

class EnvelopeFlight : public ::testing::Test {
 protected:
  FlightController fc{ControlConfig{}};
  std::int64_t now_us = 1'000'000;
  CraftPose pose{0.0, 0.0, 0.3, 0.0};

  void step() {
    now_us += kStepUs;
    fc.on_pose(PoseSample{now_us, true, pose});
    fc.update(now_us);
  }
  void to_hold() {
    step();
    ASSERT_EQ(fc.command(now_us, OperatorCommand::kArm), "");
    const std::int64_t until =
        now_us + static_cast<std::int64_t>(fc.config().arm_gesture_ms) * kMsUs;
    while (now_us < until) step();
    ASSERT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "");
    for (int i = 0; i < 500 && fc.status().state == FlightState::kTakeOff; ++i) {
      step();
      pose.z_m = fc.status().setpoint.z_m;  // the ideal craft follows the height setpoint
    }
    ASSERT_EQ(fc.status().state, FlightState::kHold);
  }
  /// The invariant of the contract: finite, inside the fence around home, under the ceiling.
  void expect_inside_envelope() const {
    const CraftPose& sp = fc.status().setpoint;
    const ControlConfig& c = fc.config();
    ASSERT_TRUE(std::isfinite(sp.x_m) && std::isfinite(sp.y_m) && std::isfinite(sp.z_m) &&
                std::isfinite(sp.yaw_deg));
    EXPECT_LE(std::hypot(sp.x_m, sp.y_m), c.max_distance_from_home_m + 1e-9);  // home = (0, 0) here
    EXPECT_LE(sp.z_m, c.max_height_m + 1e-9);
    EXPECT_GE(sp.z_m, 0.0);
  }
};

TEST_F(EnvelopeFlight, ManualStepTable) {
  struct Row {
    const char* name;
    double forward_m, left_m, up_m, yaw_ccw_deg;
    int repeat;
    bool accepted;
    double x_m, z_m;  // expected setpoint after the steps (y stays 0, heading +x)
  };
  // GIVEN hold at (0, 0, 1.7) facing +x, home (0, 0); 5 m fence, 3 m ceiling, 1 m / 90 deg steps
  const Row table[] = {
      {"one key press", 0.1, 0, 0, 0, 1, true, 0.1, 1.7},
      {"largest step", 1.0, 0, 0, 0, 1, true, 1.0, 1.7},
      {"forward 50 m (issue: setpoint x 50.1)", 50, 0, 0, 0, 1, false, 0, 1.7},
      {"back 50 m", -50, 0, 0, 0, 1, false, 0, 1.7},
      {"up 100 m (issue: setpoint z 101)", 0, 0, 100, 0, 1, false, 0, 1.7},
      {"forward 1e308 twice (issue: x = inf)", kHuge, 0, 0, 0, 2, false, 0, 1.7},
      {"up 1e308 (issue: height loop stops)", 0, 0, kHuge, 0, 1, false, 0, 1.7},
      {"down -1e308", 0, 0, -kHuge, 0, 1, false, 0, 1.7},
      {"NaN forward", kNaN, 0, 0, 0, 1, false, 0, 1.7},
      {"inf left", 0, kInf, 0, 0, 1, false, 0, 1.7},
      {"-inf up", 0, 0, -kInf, 0, 1, false, 0, 1.7},
      {"NaN yaw", 0, 0, 0, kNaN, 1, false, 0, 1.7},
      {"huge yaw", 0, 0, 0, kHuge, 1, false, 0, 1.7},
      {"yaw over the limit", 0, 0, 0, 91, 1, false, 0, 1.7},
      {"1 m forward x 20 stops at the fence", 1.0, 0, 0, 0, 20, true, 5.0, 1.7},
      {"1 m up x 20 stops at the ceiling", 0, 0, 1.0, 0, 20, true, 0, 3.0},
      {"1 m down x 20 stops at 2 x motor-stop height", 0, 0, -1.0, 0, 20, true, 0, 0.3},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    fc = FlightController{ControlConfig{}};
    now_us = 1'000'000;
    pose = CraftPose{0.0, 0.0, 0.3, 0.0};
    to_hold();
    // WHEN the manual step arrives (repeatedly)
    std::string result;
    for (int i = 0; i < row.repeat; ++i) {
      result = fc.nudge(now_us, row.forward_m, row.left_m, row.up_m, row.yaw_ccw_deg);
      step();
    }
    // THEN it is refused, or the setpoint moved and stays inside the envelope
    EXPECT_EQ(result.empty(), row.accepted) << result;
    expect_inside_envelope();
    EXPECT_NEAR(fc.status().setpoint.x_m, row.x_m, 1e-9);
    EXPECT_NEAR(fc.status().setpoint.y_m, 0.0, 1e-9);
    EXPECT_NEAR(fc.status().setpoint.z_m, row.z_m, 1e-9);
    EXPECT_EQ(fc.status().state, FlightState::kHold);
  }
}

TEST_F(EnvelopeFlight, ManualStepClampIsReported) {
  to_hold();
  for (int i = 0; i < 6; ++i) ASSERT_EQ(fc.nudge(now_us, 0.0, 0.0, 1.0, 0.0), "");
  EXPECT_NE(fc.status().last_event.find("clamped"), std::string::npos) << fc.status().last_event;
}

TEST_F(EnvelopeFlight, WaypointTable) {
  struct Row {
    const char* name;
    double x_m, y_m;
    bool accepted;
  };
  // GIVEN hold at home (0, 0); max_waypoint_distance_m 10 from the craft, 5 m fence from home
  const Row table[] = {
      {"inside", 2.0, 0.0, true},
      {"negative inside", -3.0, -3.0, true},
      {"within 10 m of the craft but outside the fence", 6.0, 0.0, false},
      {"negative outside", -8.0, 0.0, false},
      {"huge", kHuge, 0.0, false},
      {"-huge", 0.0, -kHuge, false},
      {"NaN", kNaN, 0.0, false},
      {"inf", kInf, 0.0, false},
      {"-inf", 0.0, -kInf, false},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    fc = FlightController{ControlConfig{}};
    now_us = 1'000'000;
    pose = CraftPose{0.0, 0.0, 0.3, 0.0};
    to_hold();
    const CraftPose before = fc.status().setpoint;
    // WHEN the map is clicked there
    const std::string result = fc.set_waypoint(now_us, row.x_m, row.y_m);
    step();
    // THEN it is refused (setpoint and state unchanged) or flown, inside the envelope
    EXPECT_EQ(result.empty(), row.accepted) << result;
    expect_inside_envelope();
    if (!row.accepted) {
      EXPECT_EQ(fc.status().state, FlightState::kHold);
      EXPECT_EQ(fc.status().setpoint.x_m, before.x_m);
      EXPECT_EQ(fc.status().setpoint.y_m, before.y_m);
    } else {
      EXPECT_EQ(fc.status().state, FlightState::kGoToWaypoint);
    }
  }
}

TEST_F(EnvelopeFlight, WaypointFenceIsAroundHomeNotTheCraft) {
  // GIVEN the craft held 4 m east of home
  to_hold();
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(fc.nudge(now_us, 1.0, 0.0, 0.0, 0.0), "");
    for (int k = 0; k < 10; ++k) {  // the craft follows in small steps (under the pose-jump gate)
      pose.x_m += 0.1;
      step();
    }
  }
  // WHEN waypoints 2 m further east / 2 m back west are clicked THEN only the one inside is flown
  EXPECT_NE(fc.set_waypoint(now_us, 6.0, 0.0), "");
  EXPECT_EQ(fc.set_waypoint(now_us, 2.0, 0.0), "");
}

TEST(EnvelopeConfig, TakeOffHeightAndLimitsValidated) {
  struct Row {
    const char* name;
    void (*apply)(ControlConfig&);
    bool valid;
  };
  const Row table[] = {
      {"defaults", [](ControlConfig&) {}, true},
      {"hold above the ceiling", [](ControlConfig& c) { c.hold_height_m = 3.5; }, false},
      {"hold 100 m", [](ControlConfig& c) { c.hold_height_m = 100.0; }, false},
      {"hold NaN", [](ControlConfig& c) { c.hold_height_m = kNaN; }, false},
      {"hold inf", [](ControlConfig& c) { c.hold_height_m = kInf; }, false},
      {"hold negative", [](ControlConfig& c) { c.hold_height_m = -1.0; }, false},
      {"ceiling NaN", [](ControlConfig& c) { c.max_height_m = kNaN; }, false},
      {"ceiling inf", [](ControlConfig& c) { c.max_height_m = kInf; }, false},
      {"ceiling huge", [](ControlConfig& c) { c.max_height_m = kHuge; }, false},
      {"ceiling negative", [](ControlConfig& c) { c.max_height_m = -3.0; }, false},
      {"ceiling below hold", [](ControlConfig& c) { c.max_height_m = 1.0; }, false},
      {"fence NaN", [](ControlConfig& c) { c.max_distance_from_home_m = kNaN; }, false},
      {"fence huge", [](ControlConfig& c) { c.max_distance_from_home_m = kHuge; }, false},
      {"fence 0", [](ControlConfig& c) { c.max_distance_from_home_m = 0.0; }, false},
      {"fence negative", [](ControlConfig& c) { c.max_distance_from_home_m = -5.0; }, false},
      {"manual step limit below one key press",
       [](ControlConfig& c) { c.max_manual_step_m = 0.05; }, false},
      {"manual step limit inf", [](ControlConfig& c) { c.max_manual_step_m = kInf; }, false},
      {"manual turn limit over 180", [](ControlConfig& c) { c.max_manual_yaw_step_deg = 360.0; },
       false},
      {"a 20 m room",
       [](ControlConfig& c) {
         c.max_distance_from_home_m = 20.0;
         c.max_height_m = 6.0;
       },
       true},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    ControlConfig c;
    row.apply(c);
    EXPECT_EQ(testing::problem(c).empty(), row.valid) << testing::problem(c);
    if (!row.valid) {
      EXPECT_THROW(FlightController{c}, std::invalid_argument);
    }
  }
}

TEST_F(EnvelopeFlight, TakeOffAboveTheCeilingIsHeldAtIt) {
  // GIVEN a pose above the ceiling at take-off (a hostile or broken estimate)
  pose = CraftPose{0.0, 0.0, 3.6, 0.0};
  step();
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kArm), "");
  const std::int64_t until = now_us + static_cast<std::int64_t>(fc.config().arm_gesture_ms) * kMsUs;
  while (now_us < until) step();
  // WHEN take-off is commanded THEN the setpoint never leaves the ceiling
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kTakeOff), "");
  for (int i = 0; i < 100; ++i) {
    step();
    expect_inside_envelope();
  }
}

TEST_F(EnvelopeFlight, LandingFromAboveTheCeilingStartsAtIt) {
  // GIVEN hold, then the estimate climbs above the ceiling in small steps (gusts, drift)
  to_hold();
  for (int i = 0; i < 60; ++i) {
    pose.z_m += 0.05;
    step();
  }
  ASSERT_GT(pose.z_m, fc.config().max_height_m);
  // WHEN land is commanded THEN the height setpoint starts at the ceiling and sinks from there,
  // x/y where the craft is
  ASSERT_EQ(fc.command(now_us, OperatorCommand::kLand), "");
  step();
  EXPECT_LE(fc.status().setpoint.z_m, fc.config().max_height_m);
  EXPECT_EQ(fc.status().setpoint.x_m, pose.x_m);
  for (int i = 0; i < 100; ++i) {
    step();
    expect_inside_envelope();
  }
}

TEST_F(EnvelopeFlight, RandomHostileOperatorNeverLeavesTheEnvelope) {
  // GIVEN hold WHEN 3000 seeded random operator requests (every path, hostile values) arrive
  // between control steps THEN after each one the setpoint is finite and inside the envelope
  to_hold();
  std::mt19937 rng(17);
  const double values[] = {kNaN, kInf, -kInf, kHuge, -kHuge, kMax, -kMax, 50.0, -50.0, 6.0,
                           -6.0, 1.0,  -1.0,  0.1,   -0.1,   0.0,  3.0,   -3.0, 90.0,  -90.0};
  auto pick = [&] {
    return values[std::uniform_int_distribution<std::size_t>(0, std::size(values) - 1)(rng)];
  };
  for (int i = 0; i < 3000; ++i) {
    switch (std::uniform_int_distribution<int>(0, 9)(rng)) {
      case 0:
        fc.set_waypoint(now_us, pick(), pick());
        break;
      case 1:
        fc.command(now_us, OperatorCommand::kTakeOff);
        break;
      default:
        fc.nudge(now_us, pick(), pick(), pick(), pick());
        break;
    }
    // the ideal craft follows the setpoint, 5 cm per step
    const CraftPose& sp = fc.status().setpoint;
    pose.x_m += std::clamp(sp.x_m - pose.x_m, -0.05, 0.05);
    pose.y_m += std::clamp(sp.y_m - pose.y_m, -0.05, 0.05);
    pose.z_m += std::clamp(sp.z_m - pose.z_m, -0.05, 0.05);
    step();
    ASSERT_NO_FATAL_FAILURE(expect_inside_envelope());
    ASSERT_TRUE(fc.status().state == FlightState::kHold ||
                fc.status().state == FlightState::kGoToWaypoint)
        << to_string(fc.status().state);
  }
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
