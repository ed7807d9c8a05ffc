// Stick percent -> PWM microseconds, with the channel ranges passed in (they belong to
// protocol/control's spec; these tests use an illustrative 1000..2000 us range).
#include <gtest/gtest.h>

#include <cmath>

#include "core/stick_mapping.hpp"

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
      {0.0, 1500, 1000}, {100.0, 1900, 2000}, {-100.0, 1100, 1000}, {50.0, 1700, 1500},
      {250.0, 1900, 2000}, {-250.0, 1100, 1000}, {std::nan(""), 1500, 1000},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.pct);
    EXPECT_EQ(centred_to_us(row.pct, centred), row.centred_us);
    EXPECT_EQ(throttle_to_us(row.pct, throttle), row.throttle_us);
  }
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
