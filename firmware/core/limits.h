// Every numeric constant of the firmware's behaviour, defined once, with its unit in the name and
// the reason for its value. The ground-station side never redefines these; tests read them from
// here (firmware/tools/fw_limits.py). The protocol's valid ranges come from the generated
// rgbd_control/control_spec_generated.h (protocol/control/control_spec.json).
//
// Channel order is ArduPilot's RC input order: 1 roll, 2 pitch, 3 throttle, 4 yaw.
#ifndef FIRMWARE_CORE_LIMITS_H_
#define FIRMWARE_CORE_LIMITS_H_

#include <stdint.h>

#include "rgbd_control/control_spec_generated.h"

namespace fw {

/// Firmware version reported in every reply ("fw" field).
#define FW_VERSION_STRING "0.1.0"

// ---- channels
// -------------------------------------------------------------------------------------
constexpr uint8_t kChannelCount = 4;
constexpr uint8_t kChRoll = 0;      ///< APM RC input 1
constexpr uint8_t kChPitch = 1;     ///< APM RC input 2
constexpr uint8_t kChThrottle = 2;  ///< APM RC input 3
constexpr uint8_t kChYaw = 3;       ///< APM RC input 4

// ---- PWM frame
// -----------------------------------------------------------------------------------
/// 50 Hz RC frame: the rate of a standard RC receiver, which the APM 2.6 RC input decoder expects.
constexpr uint16_t kPwmFramePeriodUs = 20000;
/// Protocol range of every commanded channel: the standard 1000-2000 us RC pulse
/// (control_spec.json).
constexpr uint16_t kCommandMinUs = rgbd_control::kChannelMinUs;
constexpr uint16_t kCommandMaxUs = rgbd_control::kChannelMaxUs;
/// Stick centre: zero roll/pitch angle and zero yaw rate in ArduCopter (RCx_TRIM default 1500).
constexpr uint16_t kNeutralUs = 1500;
/// Throttle stick fully down: ArduCopter RC3_MIN default 1000 ("zero throttle"), above
/// FS_THR_VALUE.
constexpr uint16_t kThrottleLowUs = 1000;

// ---- hard limits while armed (clamped, never rejected)
// --------------------------------------------
/// Roll/pitch +-250 us = +-50 % stick = +-22.5 deg lean with ArduCopter's default ANGLE_MAX 45 deg:
/// far more than the indoor position controller needs (thesis: small corrections around hover), but
/// a runaway controller cannot command a lean that loses altitude or flips the craft in a small
/// room.
constexpr uint16_t kRollMinUs = 1250;
constexpr uint16_t kRollMaxUs = 1750;
constexpr uint16_t kPitchMinUs = 1250;
constexpr uint16_t kPitchMaxUs = 1750;
/// Yaw +-250 us = +-50 % of ArduCopter's default 200 deg/s full-stick yaw rate (100 deg/s): enough
/// to turn towards a target, not enough to spin the Kinect's view into motion blur.
constexpr uint16_t kYawMinUs = 1250;
constexpr uint16_t kYawMaxUs = 1750;
/// Below this throttle the craft cannot be airborne (motors at or near idle), so the full yaw range
/// is allowed: ArduCopter arms/disarms on the stick gesture throttle low + yaw fully right/left
/// held for a few seconds (yaw > ~1900 us / < ~1100 us), which the yaw limit above would otherwise
/// block.
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
// Design (docs/failsafe.md): the firmware does not try to land the craft itself. It behaves like an
// RC receiver with the "low throttle" failsafe ArduPilot recommends: neutral sticks and a throttle
// pulse below FS_THR_VALUE, which hands the craft to ArduCopter's own barometer-controlled LAND
// (FS_THR_ENABLE = 3, LAND_SPEED 50 cm/s) in every flight mode. Required APM parameters are listed
// in docs/firmware.md.
/// No valid command for this long -> failsafe. 250 ms = 12 missed commands at the thesis's ~50 Hz
/// command rate: long enough to ride out WiFi jitter, short enough that the craft has not drifted
/// far.
constexpr uint32_t kFailsafeTimeoutMs = 250;
/// ArduCopter's radio failsafe threshold FS_THR_VALUE (default 975 us, required setting).
constexpr uint16_t kApmFsThrValueUs = 975;
/// Consecutive RC reads below FS_THR_VALUE ArduCopter needs before its radio failsafe (radio.cpp
/// FS_COUNTER = 3, one read per 20 ms frame = 60 ms). Until then set_throttle_and_failsafe() keeps
/// the last throttle above the threshold and does not pass the low pulse on to the flight mode;
/// then it switches to LAND. So the step to kFailsafeThrottleUs is never seen as a throttle cut by
/// any flight mode (Stabilize or AltHold) while FS_THR_ENABLE != 0: it is the hand-over signal.
constexpr uint8_t kApmFsCounterFrames = 3;
/// The APM's LAND takes over this long after the failsafe throttle is first output.
constexpr uint32_t kApmLandHandoverMs = kApmFsCounterFrames * (kPwmFramePeriodUs / 1000);
/// ArduPilot treats a pulse shorter than 900 us as no signal (RC input validity floor).
constexpr uint16_t kApmRcPulseMinValidUs = 900;
/// Failsafe throttle, output from the engage instant on as a step (no ramp): 25 us below
/// FS_THR_VALUE (margin for the APM's input-capture jitter), 50 us above the validity floor. Why a
/// step: any throttle above FS_THR_VALUE on the way down IS flown by the APM - in AltHold every
/// value below 1400 us commands a descent of up to 2.5 m/s (the old 1500 -> 1300 -> 950 us ramp
/// touched down at 0.95 m/s in HIL), in Stabilize every value below hover is a fall (3.35 m/s). The
/// step hands over to LAND 60 ms after engage, measured 0.49 m/s touchdown in both modes.
constexpr uint16_t kFailsafeThrottleUs = 950;
static_assert(kFailsafeThrottleUs < kApmFsThrValueUs, "failsafe throttle must trigger FS_THR");
static_assert(kFailsafeThrottleUs > kApmRcPulseMinValidUs,
              "failsafe throttle must be a valid pulse");
static_assert(kThrottleLowUs > kApmFsThrValueUs,
              "disarmed/ground throttle must not trigger FS_THR");

// ---- serial request link
// --------------------------------------------------------------------------
/// Longest request line (bytes, without the newline; control_spec.json max_request_bytes). The
/// longest valid control request is 93 bytes; 128 leaves margin and bounds the line buffer in the
/// ATmega's 2 KB RAM.
constexpr uint8_t kMaxRequestBytes = rgbd_control::kMaxRequestBytes;
static_assert(rgbd_control::kMaxRequestBytes <= 255, "the line assembler counts in uint8_t");
/// A request line that gets no byte for this long before its newline is discarded with a 408 reply
/// (silence, not line duration: a long line arriving steadily is never cut). The bridge forwards
/// whole requests back to back (10 us per byte at 1 Mbaud), so 100 ms of silence only happens to a
/// truncated request.
constexpr uint32_t kLineStallTimeoutMs = 100;
/// Longest valid control request line (bytes, without its line end): the sequence number at its
/// 10-digit maximum, `PUT
/// /control?seq=4294967295&arm=1&roll=2000&pitch=2000&thr=2000&yaw=2000&mac=` and 16 hex digits
/// (checked against the protocol codec by hil/arduino/tests/test_simavr.py).
constexpr uint8_t kLongestValidRequestBytes = 93;
/// The same on the wire, with a "\r\n" line end.
constexpr uint8_t kLongestValidRequestLineBytes = kLongestValidRequestBytes + 2;
/// Requests the bridge RX ring holds behind the one being answered. While the main loop checks a
/// request and formats its reply (6.1 ms in simavr, SipHash 2.7 ms of it) it reads no byte; the
/// bridge delivers a byte every 10 us at 1 Mbaud (20-40 us from the WiFi bridge under test), so
/// 150-610 bytes can arrive meanwhile - up to the whole rest of a burst of three requests. While
/// the reply goes out (196-240 bytes, 2.0-2.4 ms on the wire) the main loop moves the next request
/// into the line assembler. So three requests back to back are kept at any byte period; a third
/// queued one (95 B more) would pass the 75 % static RAM budget. docs/firmware.md ("Receive path")
/// has the measured limit.
constexpr uint8_t kBridgeRxQueuedRequests = 2;
/// Bridge RX ring (bytes): the queued requests, plus the slot a ring keeps empty to tell full from
/// empty and one for a cut marker (core/rx_ring.h). 192 B: RAM stays below the 75 % static budget.
constexpr uint8_t kBridgeRxRingBytes = kBridgeRxQueuedRequests * kLongestValidRequestLineBytes + 2;

}  // namespace fw

#endif  // FIRMWARE_CORE_LIMITS_H_
