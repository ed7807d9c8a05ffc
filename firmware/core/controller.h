// The command side of the firmware: authenticates and validates each request line, runs the arming
// and failsafe state machines and produces the four RC channel pulse widths. Time is passed in
// (now_ms from the caller's millisecond clock; wrap-around safe). No globals; the key is copied in.
// Not thread-safe: call from one context (the main loop).
//
// States: kDisarmed -> (arm=1, throttle <= kArmThrottleMaxUs) -> kArmed
//         kArmed    -> (arm=0) -> kDisarmed
//         kArmed    -> (no valid command for kFailsafeTimeoutMs) -> kFailsafe
//         kFailsafe -> (arm=0) -> kDisarmed ; arm=1 in kFailsafe is refused (403): a fresh arm is
//         needed.
// Request checks, in order: syntax (400/404/405) -> key present (503) -> MAC (401) -> sequence
// (409)
// -> ranges (422) -> state (403) -> applied (200). Only a 200 changes outputs, the last accepted
// sequence number, or the failsafe timer. Sequence numbers stay stale across resets (seq_store.h).
#ifndef FIRMWARE_CORE_CONTROLLER_H_
#define FIRMWARE_CORE_CONTROLLER_H_

#include <stddef.h>
#include <stdint.h>

#include "imu_cache.h"
#include "key_store.h"
#include "limits.h"
#include "request_parser.h"
#include "seq_store.h"
#include "status.h"

namespace fw {

enum class ArmState : uint8_t { kDisarmed, kArmed, kFailsafe };

const char* arm_state_name(ArmState s);

/// Reply buffer size that holds the longest possible reply line (checked by a unit test).
constexpr size_t kReplyBufferBytes = 272;

class Controller {
 public:
  /// `key`: kKeyBytes bytes, or nullptr when no valid key is provisioned (all commands get 503).
  /// `seq_floor`: the persisted sequence floor (load_seq_floor); numbers at or below it are stale.
  /// `seq_store`: where new floors are persisted (nullptr: not persisted, e.g. in unit tests that
  /// do not care); must outlive the controller.
  explicit Controller(const uint8_t* key, uint32_t seq_floor = 0, SeqStore* seq_store = nullptr);

  /// Handles one complete request line received at now_ms and writes the reply line (ending in
  /// '\n', NUL-terminated) into reply[0..cap). Returns the reply length without the NUL.
  size_t handle_line(const char* line, size_t len, uint32_t now_ms, const ImuCache& imu,
                     char* reply, size_t cap);
  /// Writes an error reply for a line the assembler discarded (kTooLong / kStalled).
  size_t reply_error(Status status, uint32_t now_ms, const ImuCache& imu, char* reply,
                     size_t cap) const;

  /// Advances the failsafe state machine to now_ms (call every main-loop pass).
  void update(uint32_t now_ms);
  /// Pulse widths (us) to output now, ArduPilot order (roll, pitch, throttle, yaw): a function of
  /// the state only (call update() first so the failsafe deadline is applied).
  void outputs_us(uint16_t out_us[kChannelCount]) const;

  ArmState state() const { return state_; }
  uint32_t last_seq() const { return last_seq_; }
  bool has_key() const { return has_key_; }
  /// Bit i set when channel i of the last applied command was clamped by a hard limit.
  uint8_t clamped_mask() const { return clamped_mask_; }
  /// Time failsafe engaged (valid in kFailsafe): last valid command + kFailsafeTimeoutMs.
  uint32_t failsafe_start_ms() const { return failsafe_start_ms_; }

 private:
  Status apply_control(const ParsedRequest& r, uint32_t now_ms);
  size_t write_reply(Status status, uint32_t now_ms, const ImuCache& imu, char* reply,
                     size_t cap) const;

  uint8_t key_[kKeyBytes];
  bool has_key_ = false;
  ArmState state_ = ArmState::kDisarmed;
  uint32_t last_seq_ = 0;
  uint32_t seq_reserved_ = 0;  ///< persisted floor: accepting a number above it persists a new one
  SeqStore* seq_store_ = nullptr;
  uint16_t command_us_[kChannelCount];  ///< clamped command being output while armed
  uint8_t clamped_mask_ = 0;
  uint32_t last_valid_ms_ = 0;
  uint32_t failsafe_start_ms_ = 0;
};

}  // namespace fw

#endif  // FIRMWARE_CORE_CONTROLLER_H_
