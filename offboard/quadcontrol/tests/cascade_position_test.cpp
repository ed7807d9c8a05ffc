// The cascaded position law (core/cascade_position.hpp): table-driven GIVEN/WHEN/THEN tests, time
// passed in.
#include "core/cascade_position.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/control_config.hpp"
#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr double kG = 9.80665;
constexpr double kRadToDeg = 57.29577951308232;
constexpr double kLeanLimitPct = 20.0;
constexpr std::int64_t kStepUs = 33333;  // 30 fps poses

/// The stick an acceleration asks for with ANGLE_MAX 45 deg.
double stick_for(double accel_mss) { return std::atan(accel_mss / kG) * kRadToDeg / 45.0 * 100.0; }

CascadeGains gains(double kx, double kv, double ki) {
  CascadeGains g;
  g.position_kp_per_s = kx;
  g.velocity_kp_per_s = kv;
  g.velocity_ki_per_s2 = ki;
  return g;
}

TEST(CascadePosition, FirstStepIsPositionThroughVelocityToLean) {
  struct Row {
    const char* name;
    BodyVector error_m;
    BodyVector velocity_m_per_s;
    BodyVector expected_accel_mss;  // kv * (kx * e - v), no integral on the first step
  };
  const Row table[] = {
      {"at rest on the setpoint", {0, 0}, {0, 0}, {0, 0}},
      {"setpoint 0.1 m ahead", {0.1, 0}, {0, 0}, {0.31, 0}},
      {"setpoint 0.1 m to the left", {0, 0.1}, {0, 0}, {0, 0.31}},
      {"moving towards it at the asked speed", {0.1, 0}, {0.1, 0}, {0, 0}},
      {"drifting right while on the setpoint", {0, 0}, {0, -0.2}, {0, 0.62}},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    // GIVEN the cascade with kx 1/s, kv 3.1/s
    CascadePosition law(gains(1.0, 3.1, 1.0), kLeanLimitPct);
    // WHEN it runs once
    const auto out = law.update(1'000'000, row.error_m, row.velocity_m_per_s);
    // THEN the lean is atan(a / g) of the velocity loop's acceleration, as stick percent
    ASSERT_TRUE(out);
    EXPECT_NEAR(out->forward, stick_for(row.expected_accel_mss.forward), 1e-9);
    EXPECT_NEAR(out->left, stick_for(row.expected_accel_mss.left), 1e-9);
    EXPECT_FALSE(law.last_terms().saturated);
  }
}

TEST(CascadePosition, LeanIsLimitedAndTheIntegratorDoesNotWindUpWhileClamped) {
  // GIVEN a craft 3 m behind its setpoint, at rest (the correction speed is capped at 0.5 m/s,
  // kv 10/s asks for 5 m/s^2: beyond the 20 % stick = 9 deg lean)
  CascadePosition law(gains(1.0, 10.0, 2.0), kLeanLimitPct);
  std::int64_t t = 1'000'000;
  std::optional<BodyVector> out;
  // WHEN it runs for 5 s with the error unchanged
  for (int i = 0; i < 150; ++i) out = law.update(t += kStepUs, {3.0, 0.0}, BodyVector{0.0, 0.0});
  // THEN the stick sits at the limit and the integrator stayed where it was when it saturated (0)
  ASSERT_TRUE(out);
  EXPECT_DOUBLE_EQ(out->forward, kLeanLimitPct);
  EXPECT_TRUE(law.last_terms().saturated);
  EXPECT_DOUBLE_EQ(law.last_terms().integral_mss.forward, 0.0);
  EXPECT_NEAR(law.last_terms().velocity_setpoint_m_per_s.forward, 0.5, 1e-12);
}

TEST(CascadePosition, IntegratorLearnsAConstantDisturbanceWithinItsLimit) {
  struct Row {
    const char* name;
    double limit_mss;
    double expected_integral_mss;
  };
  // A craft held 0.05 m short of its setpoint at rest: velocity error 0.05 m/s, ki 2/s^2 ->
  // 0.1 m/s^2 per second.
  const Row table[] = {{"within the limit after 3 s", 1.0, 0.3}, {"capped", 0.2, 0.2}};
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    CascadeGains g = gains(1.0, 3.0, 2.0);
    g.integral_limit_mss = row.limit_mss;
    CascadePosition law(g, kLeanLimitPct);
    std::int64_t t = 1'000'000;
    law.update(t, {0.05, 0.0}, BodyVector{0.0, 0.0});
    for (int i = 0; i < 90; ++i) law.update(t += kStepUs, {0.05, 0.0}, BodyVector{0.0, 0.0});
    EXPECT_NEAR(law.last_terms().integral_mss.forward, row.expected_integral_mss, 1e-3);
    EXPECT_DOUBLE_EQ(law.last_terms().integral_mss.left, 0.0);
  }
}

TEST(CascadePosition, WithoutAMeasuredVelocityItDifferencesTheError) {
  // GIVEN no estimator: the craft closes a 0.2 m error at 0.3 m/s (the error shrinks by 1 cm per
  // 33.3 ms), setpoint still
  CascadePosition law(gains(1.0, 3.0, 0.0), kLeanLimitPct);
  law.update(1'000'000, {0.20, 0.0});
  // WHEN the next pose comes
  law.update(1'000'000 + kStepUs, {0.19, 0.0});
  // THEN the velocity is the error's change, and the law brakes (0.19 m/s asked, 0.3 m/s flown)
  EXPECT_NEAR(law.last_terms().velocity_m_per_s.forward, 0.3, 1e-3);
  EXPECT_LT(law.last_terms().acceleration_mss.forward, 0.0);
}

TEST(CascadePosition, FeedForwardFliesTheSetpointsVelocityWithoutAnError) {
  // GIVEN a dash: the setpoint moves forward at 1 m/s and the craft keeps up exactly
  CascadePosition law(gains(1.0, 3.1, 1.0), kLeanLimitPct);
  std::int64_t t = 1'000'000;
  for (int i = 0; i < 30; ++i) {
    // WHEN the error is zero and the craft flies at the feed-forward velocity
    const auto out = law.update(t += kStepUs, {0.0, 0.0}, BodyVector{1.0, 0.0}, {1.0, 0.0});
    // THEN no lean is asked (no lag to make up)
    ASSERT_TRUE(out);
    EXPECT_NEAR(out->forward, 0.0, 1e-12);
  }
  // ... and the same craft without the feed-forward is braked back towards the setpoint
  CascadePosition plain(gains(1.0, 3.1, 1.0), kLeanLimitPct);
  const auto out = plain.update(t, {0.0, 0.0}, BodyVector{1.0, 0.0});
  EXPECT_LT(out->forward, -5.0);
}

TEST(CascadePosition, BadInputsAreRejectedAndLeaveTheStateUnchanged) {
  constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  CascadePosition law(gains(1.0, 3.0, 2.0), kLeanLimitPct);
  ASSERT_TRUE(law.update(1'000'000, {0.05, 0.0}, BodyVector{0.0, 0.0}));
  ASSERT_TRUE(law.update(2'000'000, {0.05, 0.0}, BodyVector{0.0, 0.0}));
  const double integral = law.last_terms().integral_mss.forward;
  EXPECT_GT(integral, 0.0);
  EXPECT_FALSE(law.update(3'000'000, {kNan, 0.0}, BodyVector{0.0, 0.0}));
  EXPECT_FALSE(law.update(3'000'000, {0.05, 0.0}, BodyVector{kInf, 0.0}));
  EXPECT_FALSE(law.update(3'000'000, {0.05, 0.0}, BodyVector{0.0, 0.0}, {0.0, kNan}));
  EXPECT_FALSE(law.update(2'000'000, {0.05, 0.0}, BodyVector{0.0, 0.0}));  // time not forward
  EXPECT_DOUBLE_EQ(law.last_terms().integral_mss.forward, integral);
  // reset() forgets the integrator; restart() keeps it
  law.restart();
  ASSERT_TRUE(law.update(3'000'000, {0.0, 0.0}, BodyVector{0.0, 0.0}));
  EXPECT_DOUBLE_EQ(law.last_terms().integral_mss.forward, integral);
  law.reset();
  ASSERT_TRUE(law.update(4'000'000, {0.0, 0.0}, BodyVector{0.0, 0.0}));
  EXPECT_DOUBLE_EQ(law.last_terms().integral_mss.forward, 0.0);
}

TEST(CascadePosition, GainValidation) {
  struct Row {
    const char* name;
    void (*edit)(CascadeGains&);
    bool valid;
  };
  const Row table[] = {
      {"defaults", [](CascadeGains&) {}, true},
      {"no integral", [](CascadeGains& g) { g.velocity_ki_per_s2 = 0.0; }, true},
      {"negative gain", [](CascadeGains& g) { g.velocity_kp_per_s = -1.0; }, false},
      {"NaN gain", [](CascadeGains& g) { g.position_kp_per_s = std::nan(""); }, false},
      {"integral limit beyond g", [](CascadeGains& g) { g.integral_limit_mss = 20.0; }, false},
      {"zero correction speed", [](CascadeGains& g) { g.max_correction_speed_m_per_s = 0.0; },
       false},
      {"ANGLE_MAX 5 deg", [](CascadeGains& g) { g.angle_max_deg = 5.0; }, false},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    CascadeGains g;
    row.edit(g);
    EXPECT_EQ(testing::problem(g).empty(), row.valid) << testing::problem(g);
    if (!row.valid) {
      EXPECT_THROW(CascadePosition(g, kLeanLimitPct), std::invalid_argument);
    }
  }
  EXPECT_THROW(CascadePosition(CascadeGains{}, 0.0), std::invalid_argument);
}

TEST(CascadeConfig, PositionLawAndCascadeGainsLoadFromJsonAndRoundTrip) {
  struct Row {
    const char* json;
    bool ok;
  };
  const Row table[] = {
      {R"({"position_law": "pid"})", true},
      {R"({"position_law": "cascade", "cascade": {"velocity_ki_per_s2": 0.5}})", true},
      {R"({"position_law": "lqr"})", false},
      {R"({"position_law": 1})", false},
      {R"({"cascade": {"velocity_kp": 3.0}})", false},
      {R"({"cascade": {"velocity_kp_per_s": "fast"}})", false},
      {R"({"cascade": 2})", false},
      {R"({"max_manoeuvre_yaw_rate_deg_per_s": 45.0})", true},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.json);
    ControlConfig c;
    EXPECT_EQ(load_control_config(nlohmann::json::parse(row.json), c).empty(), row.ok);
  }
  // GIVEN a config with the thesis law and one cascade gain changed WHEN it goes through to_json
  // THEN it reads back the same, and the defaults are the cascade
  EXPECT_EQ(ControlConfig{}.position_law, PositionLaw::kCascade);
  ControlConfig c;
  ASSERT_EQ(
      load_control_config(
          nlohmann::json::parse(R"({"position_law": "pid", "cascade": {"angle_max_deg": 30}})"), c),
      "");
  ControlConfig d;
  ASSERT_EQ(load_control_config(to_json(c), d), "");
  EXPECT_EQ(d.position_law, PositionLaw::kPid);
  EXPECT_DOUBLE_EQ(d.cascade.angle_max_deg, 30.0);
  EXPECT_DOUBLE_EQ(d.cascade.velocity_kp_per_s, CascadeGains{}.velocity_kp_per_s);
  // A manoeuvre yaw rate at or above the APM's full-stick rate is refused at start-up.
  d.max_manoeuvre_yaw_rate_deg_per_s = d.apm_yaw_rate_max_deg_per_s;
  EXPECT_NE(testing::problem(d).find("max_manoeuvre_yaw_rate_deg_per_s"), std::string::npos);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
