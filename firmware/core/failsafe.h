// The failsafe outputs (see docs/failsafe.md and the reasons in limits.h): neutral sticks and a
// throttle pulse below ArduCopter's FS_THR_VALUE, from the engage instant on. The firmware does not
// fly the landing itself: this hands the craft to the APM's own radio-failsafe LAND, which
// ArduCopter enters after kApmFsCounterFrames low frames without ever flying the low pulse.
#ifndef FIRMWARE_CORE_FAILSAFE_H_
#define FIRMWARE_CORE_FAILSAFE_H_

#include <stdint.h>

#include "limits.h"

namespace fw {

/// Writes the failsafe pulse widths (us) of the four channels (ArduPilot order).
inline void failsafe_outputs_us(uint16_t out_us[kChannelCount]) {
  out_us[kChRoll] = kNeutralUs;
  out_us[kChPitch] = kNeutralUs;
  out_us[kChThrottle] = kFailsafeThrottleUs;
  out_us[kChYaw] = kNeutralUs;
}

}  // namespace fw

#endif  // FIRMWARE_CORE_FAILSAFE_H_
