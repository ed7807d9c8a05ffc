// Every numeric constant of the firmware's behaviour, defined once, with its unit in the name and the
// reason for its value. The ground-station side never redefines these: the protocol's valid ranges
// live in protocol/control/control_spec.json and a test checks this header agrees with that file.
//
// Channel order is ArduPilot's RC input order: 1 roll, 2 pitch, 3 throttle, 4 yaw.
#ifndef FIRMWARE_CORE_LIMITS_H_
#define FIRMWARE_CORE_LIMITS_H_

#include <stdint.h>

namespace fw {

/// Firmware version reported in every reply ("fw" field).
#define FW_VERSION_STRING "0.1.0"

// ---- channels -------------------------------------------------------------------------------------
constexpr uint8_t kChannelCount = 4;
constexpr uint8_t kChRoll = 0;      ///< APM RC input 1
constexpr uint8_t kChPitch = 1;     ///< APM RC input 2
constexpr uint8_t kChThrottle = 2;  ///< APM RC input 3
constexpr uint8_t kChYaw = 3;       ///< APM RC input 4

// ---- PWM frame -----------------------------------------------------------------------------------
/// 50 Hz RC frame: the rate of a standard RC receiver, which the APM 2.6 RC input decoder expects.
constexpr uint16_t kPwmFramePeriodUs = 20000;
/// Protocol range of every commanded channel: the standard 1000-2000 us RC pulse (control_spec.json).
constexpr uint16_t kCommandMinUs = 1000;
constexpr uint16_t kCommandMaxUs = 2000;
/// Stick centre: zero roll/pitch angle and zero yaw rate in ArduCopter (RCx_TRIM default 1500).
constexpr uint16_t kNeutralUs = 1500;
/// Throttle stick fully down: ArduCopter RC3_MIN default 1000 ("zero throttle"), above FS_THR_VALUE.
constexpr uint16_t kThrottleLowUs = 1000;

// ---- hard limits while armed (clamped, never rejected) --------------------------------------------
/// Roll/pitch +-250 us = +-50 % stick = +-22.5 deg lean with ArduCopter's default ANGLE_MAX 45 deg:
/// far more than the indoor position controller needs (thesis: small corrections around hover), but a
/// runaway controller cannot command a lean that loses altitude or flips the craft in a small room.
constexpr uint16_t kRollMinUs = 1250;
constexpr uint16_t kRollMaxUs = 1750;
constexpr uint16_t kPitchMinUs = 1250;
constexpr uint16_t kPitchMaxUs = 1750;
/// Yaw +-250 us = +-50 % of ArduCopter's default 200 deg/s full-stick yaw rate (100 deg/s): enough to
/// turn towards a target, not enough to spin the Kinect's view into motion blur.
constexpr uint16_t kYawMinUs = 1250;
constexpr uint16_t kYawMaxUs = 1750;
/// Below this throttle the craft cannot be airborne (motors at or near idle), so the full yaw range is
/// allowed: ArduCopter arms/disarms on the stick gesture throttle low + yaw fully right/left held for
/// a few seconds (yaw > ~1900 us / < ~1100 us), which the yaw limit above would otherwise block.
constexpr uint16_t kGroundThrottleMaxUs = 1100;
/// Throttle ceiling 1750 us: the thesis craft hovers near mid-stick (~1500 us); 1750 still climbs
/// briskly but a faulty controller cannot slam full power into an indoor ceiling.
constexpr uint16_t kThrottleMaxUs = 1750;
/// Throttle floor while armed: fully down, needed to land and for the arming gesture.
constexpr uint16_t kThrottleMinUs = 1000;

// ---- arming -------------------------------------------------------------------------------------
/// An arm command is accepted only with throttle at or below this (same value as the ground
/// threshold): arming must never produce a step to flying throttle.
constexpr uint16_t kArmThrottleMaxUs = kGroundThrottleMaxUs;

// ---- failsafe -----------------------------------------------------------------------------------
/// No valid command for this long -> failsafe. 250 ms = 12 missed commands at the thesis's ~50 Hz
/// command rate: long enough to ride out WiFi jitter, short enough that the craft has not drifted far.
constexpr uint32_t kFailsafeTimeoutMs = 250;
/// Throttle ramp during failsafe. 200 us/s takes 1 s from a 1500 us hover to the descent level: a
/// steady reduction (the thesis warns an instant drop tips the craft over and breaks props).
constexpr uint32_t kFailsafeRampUsPerS = 200;
/// Descent level: 200 us below the ~1500 us hover gives a clear but gentle sink in Stabilize mode
/// (and "descend" in AltHold, whose dead band is +-10 % around mid-stick).
constexpr uint16_t kFailsafeDescentUs = 1300;
/// Time held at the descent level before ramping further, so the craft is already sinking slowly
/// when the APM's own failsafe takes over.
constexpr uint32_t kFailsafeDescentHoldMs = 2000;
/// ArduCopter's radio failsafe threshold FS_THR_VALUE (default 975 us); configured to Land (FS_THR_ENABLE=3).
constexpr uint16_t kApmFsThrValueUs = 975;
/// Final failsafe throttle: 25 us below FS_THR_VALUE (margin for the APM's input-capture jitter) and
/// above 900 us, below which ArduPilot treats a pulse as invalid; the APM then lands under its own
/// control (LAND mode, barometer-controlled descent rate).
constexpr uint16_t kFailsafeFinalUs = 950;
static_assert(kFailsafeFinalUs < kApmFsThrValueUs, "final failsafe throttle must trigger FS_THR");

// ---- serial request link --------------------------------------------------------------------------
/// Longest request line (bytes, without the newline). The longest valid control request is 93
/// bytes (control_spec.json); 128 leaves margin and bounds the line buffer in the ATmega's 2 KB RAM.
constexpr uint8_t kMaxRequestBytes = 128;
/// A request line left incomplete this long is discarded with a 408 reply: the bridge forwards whole
/// requests, and a 128-byte line takes 2.6 ms at 500 kbaud, so 100 ms only fires on a truncated request.
constexpr uint32_t kLineStallTimeoutMs = 100;

}  // namespace fw

#endif  // FIRMWARE_CORE_LIMITS_H_
