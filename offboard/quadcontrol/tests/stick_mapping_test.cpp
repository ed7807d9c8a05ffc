// Stick percent -> PWM microseconds, with the channel ranges passed in (they belong to
// protocol/control's spec; these tests use an illustrative 1000..2000 us range).
#include "core/stick_mapping.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace rgbdquad::quadcontrol {
namespace {

TEST(StickMapping, CentredAndThrottleChannels) {
  const PwmRange centred{1100, 1500, 1900};
  const PwmRange throttle{1000, 1000, 2000};
  struct Row {
    double pct;
    std::uint16_t centred_us, throttle_us;
  };
  const Row table[] = {
      {0.0, 1500, 1000},   {100.0, 1900, 2000},  {-100.0, 1100, 1000},       {50.0, 1700, 1500},
      {250.0, 1900, 2000}, {-250.0, 1100, 1000}, {std::nan(""), 1500, 1000},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.pct);
    EXPECT_EQ(centred_to_us(row.pct, centred), row.centred_us);
    EXPECT_EQ(throttle_to_us(row.pct, throttle), row.throttle_us);
  }
}

// ArduCopter reads a high RC2 as "nose up" (pitch back): forward (+pitch %) must go out below
// neutral, or the position loop pushes the craft away from its setpoint (found by the HIL rig's
// closed-loop flight: the craft ran off backwards). Roll right, yaw clockwise: above neutral.
TEST(StickMapping, ArduCopterChannelDirections) {
  const PwmRange centred{1100, 1500, 1900};
  const PwmRanges ranges{centred, centred, centred, PwmRange{1000, 1000, 2000}};
  StickCommand s;
  s.roll_pct = 50.0;
  s.pitch_pct = 50.0;
  s.yaw_pct = 50.0;
  s.throttle_pct = 50.0;
  const PwmCommand c = to_pwm(s, ranges);
  EXPECT_EQ(c.roll_us, 1700);   // roll right
  EXPECT_EQ(c.pitch_us, 1300);  // forward = nose down = RC2 low
  EXPECT_EQ(c.yaw_us, 1700);    // clockwise
  EXPECT_EQ(c.throttle_us, 1500);
}

// With the APM's 20 us dead zone, a small stick lands just outside it; after ArduPilot removes the
// dead zone and rescales, the lean it commands is proportional to the stick (no dead band).
TEST(StickMapping, DeadZoneIsSteppedOverAndProportionalAfterTheApmRemovesIt) {
  const PwmRange r{1100, 1500, 1900};
  const double dz = 20.0;
  EXPECT_EQ(centred_to_us(0.0, r, dz), 1500);
  EXPECT_EQ(centred_to_us(100.0, r, dz), 1900);
  EXPECT_EQ(centred_to_us(-100.0, r, dz), 1100);
  EXPECT_EQ(centred_to_us(10.0, r, dz), 1558);  // 20 + 0.1 * 380
  EXPECT_EQ(centred_to_us(-10.0, r, dz), 1442);
  for (double pct : {1.0, 5.0, 25.0, 60.0}) {
    const double apm = (centred_to_us(pct, r, dz) - 1500 - dz) / (400.0 - dz);  // ArduPilot's view
    EXPECT_NEAR(apm, pct / 100.0, 1.0 / 380.0) << pct;
  }
}

// AltHold: around hover (mid-stick) the APM ignores +-THR_DZ and rescales the rest into a climb
// rate; an offset from hover is sent just outside the band, 0 % / 100 % still reach the ends.
TEST(StickMapping, ThrottleDeadBandAroundHoverIsSteppedOver) {
  const PwmRange r{1000, 1000, 2000};
  EXPECT_EQ(throttle_to_us(50.0, r, 50.0, 100.0), 1500);
  EXPECT_EQ(throttle_to_us(0.0, r, 50.0, 100.0), 1000);  // arming gesture still at the bottom
  EXPECT_EQ(throttle_to_us(100.0, r, 50.0, 100.0), 2000);
  EXPECT_EQ(throttle_to_us(60.0, r, 50.0, 100.0), 1680);  // 1500 + 100 + 0.2 * 400
  EXPECT_EQ(throttle_to_us(40.0, r, 50.0, 100.0), 1320);
  for (double pct : {51.0, 55.0, 75.0}) {
    const double climb_fraction =
        (throttle_to_us(pct, r, 50.0, 100.0) - 1600) / 400.0;  // the APM's view
    EXPECT_NEAR(climb_fraction, (pct - 50.0) / 50.0, 1.0 / 400.0) << pct;
  }
  EXPECT_EQ(throttle_to_us(60.0, r, 50.0, 0.0), 1600);  // no band: linear
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
