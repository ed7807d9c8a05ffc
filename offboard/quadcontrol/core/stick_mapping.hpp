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

/// Centred channel: -100 % -> min_us, 0 -> neutral_us, +100 % -> max_us (clamped). With a dead
/// zone (the APM's RCx_DZ, which ArduPilot subtracts before rescaling), a non-zero stick starts at
/// neutral +- deadzone_us, so what the APM acts on is proportional to pct (see ControlConfig).
inline std::uint16_t centred_to_us(double pct, const PwmRange& r, double deadzone_us = 0.0) {
  if (!std::isfinite(pct)) return r.neutral_us;
  const double p = std::clamp(pct, -100.0, 100.0) / 100.0;
  const double span = p >= 0.0 ? r.max_us - r.neutral_us : r.neutral_us - r.min_us;
  const double dz = std::clamp(deadzone_us, 0.0, span);
  const double offset = p == 0.0 ? 0.0 : std::copysign(dz, p) + p * (span - dz);
  return static_cast<std::uint16_t>(std::lround(r.neutral_us + offset));
}

/// Throttle: 0 % -> min_us, 100 % -> max_us (clamped), linear. With a dead band (the APM's AltHold
/// THR_DZ, where the stick around hover_pct commands zero climb), a throttle off hover_pct starts
/// just outside it, so the climb rate the APM commands is proportional to the offset; 0 % and
/// 100 % still map to min_us and max_us.
inline std::uint16_t throttle_to_us(double pct, const PwmRange& r, double hover_pct = 50.0,
                                    double deadband_us = 0.0) {
  if (!std::isfinite(pct)) return r.min_us;
  const double p = std::clamp(pct, 0.0, 100.0);
  const double span = r.max_us - r.min_us;
  if (deadband_us <= 0.0 || !(hover_pct > 0.0 && hover_pct < 100.0) || p == hover_pct) {
    return static_cast<std::uint16_t>(std::lround(r.min_us + p / 100.0 * span));
  }
  const double hover_us = r.min_us + hover_pct / 100.0 * span;
  if (p > hover_pct) {
    const double room = std::max(0.0, r.max_us - hover_us - deadband_us);
    return static_cast<std::uint16_t>(
        std::lround(hover_us + deadband_us + (p - hover_pct) / (100.0 - hover_pct) * room));
  }
  const double room = std::max(0.0, hover_us - r.min_us - deadband_us);
  return static_cast<std::uint16_t>(
      std::lround(hover_us - deadband_us - (hover_pct - p) / hover_pct * room));
}

/// How the APM reads the sticks (its parameters; 0 = no dead zone / band to step over).
struct ApmStickInput {
  double stick_deadzone_us = 0.0;     ///< RC1/2/4_DZ
  double throttle_deadband_us = 0.0;  ///< AltHold's THR_DZ around hover_throttle_pct
  double hover_throttle_pct = 50.0;
};

/// Stick percent -> RC pulse widths in ArduCopter's conventions: roll + (right) -> RC1 above
/// neutral; pitch + (forward, nose down) -> RC2 BELOW neutral (ArduCopter pitches nose up for a
/// high RC2, as a mode-2 transmitter whose stick pushed forward lowers the pulse); yaw +
/// (clockwise) -> RC4 above neutral; throttle 0..100 % -> RC3 min..max.
inline PwmCommand to_pwm(const StickCommand& s, const PwmRanges& ranges,
                         const ApmStickInput& apm = {}) {
  PwmCommand c;
  c.roll_us = centred_to_us(s.roll_pct, ranges.roll, apm.stick_deadzone_us);
  c.pitch_us = centred_to_us(-s.pitch_pct, ranges.pitch, apm.stick_deadzone_us);
  c.yaw_us = centred_to_us(s.yaw_pct, ranges.yaw, apm.stick_deadzone_us);
  c.throttle_us = throttle_to_us(s.throttle_pct, ranges.throttle, apm.hover_throttle_pct,
                                 apm.throttle_deadband_us);
  c.armed = s.armed;
  return c;
}

}  // namespace rgbdquad::quadcontrol
