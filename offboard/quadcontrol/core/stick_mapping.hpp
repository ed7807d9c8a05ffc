// Controller sticks (percent of deflection) -> firmware command units (RC PWM microseconds).
//
// The PWM limits are NOT defined here: they belong to protocol/control's spec (the firmware clamps
// to them). The caller passes the range of each channel as read from there; this file only does
// the linear mapping and the clamping, so a bug in the controller can never ask for more than the
// spec allows.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/flight_controller.hpp"

namespace rgbdquad::quadcontrol {

/// One RC channel's range in microseconds (from protocol/control's spec).
struct PwmRange {
  std::uint16_t min_us = 0;
  std::uint16_t neutral_us = 0;  ///< stick centre; for throttle the 0 % value is min_us
  std::uint16_t max_us = 0;
};

struct PwmRanges {
  PwmRange roll, pitch, yaw, throttle;
};

struct PwmCommand {
  std::uint16_t roll_us = 0;
  std::uint16_t pitch_us = 0;
  std::uint16_t throttle_us = 0;
  std::uint16_t yaw_us = 0;
  bool armed = false;
};

/// Centred channel: -100 % -> min_us, 0 -> neutral_us, +100 % -> max_us (clamped).
inline std::uint16_t centred_to_us(double pct, const PwmRange& r) {
  if (!std::isfinite(pct)) return r.neutral_us;
  const double p = std::clamp(pct, -100.0, 100.0) / 100.0;
  const double span = p >= 0.0 ? r.max_us - r.neutral_us : r.neutral_us - r.min_us;
  return static_cast<std::uint16_t>(std::lround(r.neutral_us + p * span));
}

/// Throttle: 0 % -> min_us, 100 % -> max_us (clamped).
inline std::uint16_t throttle_to_us(double pct, const PwmRange& r) {
  if (!std::isfinite(pct)) return r.min_us;
  const double p = std::clamp(pct, 0.0, 100.0) / 100.0;
  return static_cast<std::uint16_t>(std::lround(r.min_us + p * (r.max_us - r.min_us)));
}

inline PwmCommand to_pwm(const StickCommand& s, const PwmRanges& ranges) {
  PwmCommand c;
  c.roll_us = centred_to_us(s.roll_pct, ranges.roll);
  c.pitch_us = centred_to_us(s.pitch_pct, ranges.pitch);
  c.yaw_us = centred_to_us(s.yaw_pct, ranges.yaw);
  c.throttle_us = throttle_to_us(s.throttle_pct, ranges.throttle);
  c.armed = s.armed;
  return c;
}

}  // namespace rgbdquad::quadcontrol
