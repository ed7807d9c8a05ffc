// Per-axis PID: table-driven GIVEN/WHEN/THEN tests with time passed in.
#include "core/pid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/control_config.hpp"
#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr std::int64_t kStepUs = 20000;  // 50 Hz command rate

struct PStep {
  const char* name;
  PidGains gains;
  double setpoint, measurement, expected;
};

TEST(Pid, FirstStepIsProportionalOnlyAndClamped) {
  const PStep table[] = {
      {"roll 100 mm", {0.015, 0.0, 0.01, 20.0}, 100.0, 0.0, 1.5},
      {"roll -100 mm", {0.015, 0.0, 0.01, 20.0}, 0.0, 100.0, -1.5},
      {"roll saturates high", {0.015, 0.0, 0.01, 20.0}, 5000.0, 0.0, 20.0},
      {"roll saturates low", {0.015, 0.0, 0.01, 20.0}, -5000.0, 0.0, -20.0},
      {"yaw 90 deg", {0.06, 0.0, 0.02, 30.0}, 90.0, 0.0, 5.4},
      {"throttle 200 mm, no integral on first step",
       {0.025, 0.013, 0.02, 30.0},
       1700.0,
       1500.0,
       5.0},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    Pid pid(row.gains);
    auto out = pid.update(1000, row.setpoint, row.measurement);
    ASSERT_TRUE(out.has_value());
    EXPECT_NEAR(*out, row.expected, 1e-9);
  }
}

TEST(Pid, RejectsNonFiniteInputAndKeepsState) {
  const double bad[] = {std::numeric_limits<double>::quiet_NaN(),
                        std::numeric_limits<double>::infinity(),
                        -std::numeric_limits<double>::infinity()};
  for (double b : bad) {
    Pid pid({0.025, 0.013, 0.02, 30.0});
    ASSERT_TRUE(pid.update(0, 100.0, 0.0));
    ASSERT_TRUE(pid.update(kStepUs, 100.0, 0.0));
    const double integral = pid.integral();
    EXPECT_FALSE(pid.update(2 * kStepUs, b, 0.0));
    EXPECT_FALSE(pid.update(2 * kStepUs, 100.0, b));
    EXPECT_DOUBLE_EQ(pid.integral(), integral);
    // A good sample afterwards is accepted and the output stays finite.
    auto out = pid.update(3 * kStepUs, 100.0, 0.0);
    ASSERT_TRUE(out);
    EXPECT_TRUE(std::isfinite(*out));
  }
}

TEST(Pid, RejectsTimeNotMovingForward) {
  Pid pid({0.015, 0.0, 0.01, 20.0});
  ASSERT_TRUE(pid.update(1000, 0.0, 0.0));
  EXPECT_FALSE(pid.update(1000, 0.0, 10.0));
  EXPECT_FALSE(pid.update(999, 0.0, 10.0));
}

TEST(Pid, DerivativeActsOnMeasurementNotSetpoint) {
  // GIVEN a PD controller at rest
  Pid pid({0.0, 0.0, 0.01, 20.0});
  ASSERT_TRUE(pid.update(0, 0.0, 0.0));
  // WHEN the setpoint jumps by 1 m THEN there is no derivative kick
  auto out = pid.update(kStepUs, 1000.0, 0.0);
  ASSERT_TRUE(out);
  EXPECT_DOUBLE_EQ(*out, 0.0);
  // WHEN the measurement moves towards the setpoint at 0.5 m/s THEN the D term brakes: -0.01*500
  out = pid.update(2 * kStepUs, 1000.0, 10.0);
  ASSERT_TRUE(out);
  EXPECT_NEAR(*out, -5.0, 1e-9);
}

TEST(Pid, GivenAMeasuredRateThenTheDerivativeUsesItInsteadOfDifferences) {
  struct Row {
    const char* name;
    double rate_per_s;
    double expected;  // kp * error - kd * rate
  };
  const Row table[] = {{"moving away 200 mm/s", 200.0, 0.03 * 100.0 - 0.03 * 200.0},
                       {"at rest", 0.0, 3.0},
                       {"closing 100 mm/s", -100.0, 0.03 * 100.0 + 0.03 * 100.0}};
  for (const Row& r : table) {
    // GIVEN a PID that already saw a measurement 500 mm away (differencing would give 20000 mm/s)
    Pid pid({0.03, 0.0, 0.03, 20.0});
    ASSERT_TRUE(pid.update(0, 0.0, 400.0));
    // WHEN the next step comes with an estimated rate of change
    const auto out = pid.update(kStepUs, 0.0, -100.0, r.rate_per_s);
    // THEN the derivative is -kd * rate, not the 500 mm jump over 20 ms
    ASSERT_TRUE(out) << r.name;
    EXPECT_NEAR(*out, r.expected, 1e-9) << r.name;
  }
  Pid pid({0.03, 0.0, 0.03, 20.0});
  EXPECT_FALSE(pid.update(0, 0.0, 1.0,
                          std::numeric_limits<double>::quiet_NaN()));  // non-finite rate refused
}

TEST(Pid, IntegratesOverTime) {
  // throttle Ki 0.013/s, error 100 mm for 1 s -> integral 1.3 %
  Pid pid({0.0, 0.013, 0.0, 30.0});
  std::int64_t t = 0;
  ASSERT_TRUE(pid.update(t, 100.0, 0.0));
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(pid.update(t += kStepUs, 100.0, 0.0));
  EXPECT_NEAR(pid.integral(), 1.3, 1e-9);
}

TEST(Pid, AntiWindupOnlyWhileSaturated) {
  // GIVEN a saturating error for 10 s
  Pid pid({0.025, 0.013, 0.0, 30.0});
  std::int64_t t = 0;
  ASSERT_TRUE(pid.update(t, 2000.0, 0.0));  // P = 50 > 30: saturated
  for (int i = 0; i < 500; ++i) ASSERT_TRUE(pid.update(t += kStepUs, 2000.0, 0.0));
  // THEN the integrator did not wind up
  EXPECT_DOUBLE_EQ(pid.integral(), 0.0);
  EXPECT_TRUE(pid.last_terms().saturated);
  // WHEN the error drops below saturation THEN it integrates again
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(pid.update(t += kStepUs, 100.0, 0.0));
  EXPECT_NEAR(pid.integral(), 1.3, 1e-9);
  // WHEN saturated but the error pulls back out of saturation THEN it still integrates
  Pid neg({0.025, 0.013, 0.0, 30.0});
  t = 0;
  ASSERT_TRUE(neg.update(t, 0.0, 0.0));
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(neg.update(t += kStepUs, 100.0, 0.0));  // integral +1.3
  const double before = neg.integral();
  ASSERT_TRUE(
      neg.update(t += kStepUs, -2000.0, 0.0));  // output saturated low, error negative: frozen
  EXPECT_DOUBLE_EQ(neg.integral(), before);
}

TEST(Pid, ResetForgetsHistory) {
  Pid pid({0.0, 0.013, 0.01, 30.0});
  ASSERT_TRUE(pid.update(0, 100.0, 0.0));
  ASSERT_TRUE(pid.update(kStepUs, 100.0, 0.0));
  pid.reset();
  EXPECT_DOUBLE_EQ(pid.integral(), 0.0);
  auto out = pid.update(kStepUs / 2, 100.0, 50.0);  // earlier time accepted after reset, no D term
  ASSERT_TRUE(out);
  EXPECT_DOUBLE_EQ(*out, 0.0);
}

TEST(ControlConfig, Table31Defaults) {
  const ControlConfig c;
  EXPECT_DOUBLE_EQ(c.roll.kp, 0.015);
  EXPECT_DOUBLE_EQ(c.roll.kd, 0.01);
  EXPECT_DOUBLE_EQ(c.pitch.kp, 0.015);
  EXPECT_DOUBLE_EQ(c.yaw.kp, 0.06);
  EXPECT_DOUBLE_EQ(c.yaw.kd, 0.02);
  EXPECT_DOUBLE_EQ(c.throttle.kp, 0.025);
  EXPECT_DOUBLE_EQ(c.throttle.ki, 0.013);
  EXPECT_DOUBLE_EQ(c.throttle.kd, 0.02);
  EXPECT_DOUBLE_EQ(c.hold_height_m, 1.7);
  EXPECT_EQ(testing::problem(c), "");
}

TEST(ControlConfig, LoadsOverridesAndRejectsBadInput) {
  struct Row {
    const char* json;
    bool ok;
  };
  const Row table[] = {
      {R"({"hold_height_m": 1.2})", true},
      {R"({"roll": {"kp": 0.02}})", true},
      {R"({"hold_hieght_m": 1.2})", false},
      {R"({"roll": {"kq": 0.02}})", false},
      {R"({"roll": 3})", false},
      {R"({"hold_height_m": "high"})", false},
      {R"([1, 2])", false},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.json);
    ControlConfig c;
    EXPECT_EQ(load_control_config(nlohmann::json::parse(row.json), c).empty(), row.ok);
  }
  ControlConfig c;
  ASSERT_EQ(load_control_config(nlohmann::json::parse(R"({"roll": {"kp": 0.02}})"), c), "");
  EXPECT_DOUBLE_EQ(c.roll.kp, 0.02);
  EXPECT_DOUBLE_EQ(c.roll.kd, 0.01);  // untouched default
  // Round trip through to_json.
  ControlConfig d;
  ASSERT_EQ(load_control_config(to_json(c), d), "");
  EXPECT_DOUBLE_EQ(d.roll.kp, 0.02);
}

TEST(ControlConfig, ValidateNamesTheBadField) {
  ControlConfig c;
  c.throttle.ki = -1.0;
  EXPECT_NE(testing::problem(c).find("throttle"), std::string::npos);
  c = ControlConfig{};
  c.failsafe_landing_ms = 0.0;
  EXPECT_NE(testing::problem(c).find("failsafe_landing_ms"), std::string::npos);
  c = ControlConfig{};
  c.hold_height_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(testing::problem(c).find("hold_height_m"), std::string::npos);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
