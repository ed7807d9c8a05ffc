// The failsafe throttle timeline as a pure function of time since failsafe engaged (see
// docs/failsafe.md for the timeline with numbers). Integer arithmetic only (fits the ATmega).
#ifndef FIRMWARE_CORE_FAILSAFE_H_
#define FIRMWARE_CORE_FAILSAFE_H_

#include <stdint.h>

#include "limits.h"

namespace fw {

/// Throttle (us) `elapsed_ms` after failsafe engaged, starting from the throttle being output then.
/// Phase 1: ramp at kFailsafeRampUsPerS down to kFailsafeDescentUs (skipped when already below);
/// phase 2: hold kFailsafeDescentHoldMs (only after a phase 1);
/// phase 3: ramp at the same rate down to kFailsafeFinalUs and stay there.
inline uint16_t failsafe_throttle_us(uint16_t start_us, uint32_t elapsed_ms) {
  const uint32_t rate = kFailsafeRampUsPerS;
  uint32_t level = start_us;
  if (level > kFailsafeDescentUs) {
    const uint32_t drop = level - kFailsafeDescentUs;
    const uint32_t ramp_ms = (drop * 1000UL + rate - 1) / rate;
    if (elapsed_ms < ramp_ms) return static_cast<uint16_t>(level - elapsed_ms * rate / 1000UL);
    elapsed_ms -= ramp_ms;
    if (elapsed_ms < kFailsafeDescentHoldMs) return kFailsafeDescentUs;
    elapsed_ms -= kFailsafeDescentHoldMs;
    level = kFailsafeDescentUs;
  }
  if (level <= kFailsafeFinalUs) return kFailsafeFinalUs;
  const uint32_t ramped = elapsed_ms * rate / 1000UL;
  if (ramped >= level - kFailsafeFinalUs) return kFailsafeFinalUs;
  return static_cast<uint16_t>(level - ramped);
}

}  // namespace fw

#endif  // FIRMWARE_CORE_FAILSAFE_H_
