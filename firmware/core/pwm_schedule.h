// Maps the four channel pulse widths onto the sequential-pulse schedule the AVR timer plays: one
// 20 ms frame = pulse ch1, pulse ch2, pulse ch3, pulse ch4 back to back (each channel's pin high
// for its width), then the remaining gap. Timer1 runs at 2 ticks/us (16 MHz / prescaler 8). Pure
// functions: the AVR ISR only copies precomputed tick counts.
#ifndef FIRMWARE_CORE_PWM_SCHEDULE_H_
#define FIRMWARE_CORE_PWM_SCHEDULE_H_

#include <stdint.h>

#include "limits.h"

namespace fw {

/// Timer1 ticks per microsecond: 16 MHz CPU clock / prescaler 8.
constexpr uint16_t kTimerTicksPerUs = 2;
/// Shortest/longest pulse the schedule emits: below 900 us / above 2100 us ArduPilot treats a pulse
/// as invalid, so nothing outside that ever reaches a pin, whatever the caller passes.
constexpr uint16_t kPulseFloorUs = 900;
constexpr uint16_t kPulseCeilUs = 2100;
constexpr uint8_t kScheduleSlots = kChannelCount + 1;

/// Fills slot_ticks[0..3] with the channel pulse widths in timer ticks and slot_ticks[4] with the
/// rest of the 20 ms frame.
inline void make_pwm_schedule(const uint16_t out_us[kChannelCount],
                              uint16_t slot_ticks[kScheduleSlots]) {
  uint32_t used_us = 0;
  for (uint8_t ch = 0; ch < kChannelCount; ++ch) {
    uint16_t us = out_us[ch];
    if (us < kPulseFloorUs) us = kPulseFloorUs;
    if (us > kPulseCeilUs) us = kPulseCeilUs;
    slot_ticks[ch] = static_cast<uint16_t>(us * kTimerTicksPerUs);
    used_us += us;
  }
  slot_ticks[kChannelCount] =
      static_cast<uint16_t>((kPwmFramePeriodUs - used_us) * kTimerTicksPerUs);
}

}  // namespace fw

#endif  // FIRMWARE_CORE_PWM_SCHEDULE_H_
