// Ground-station codec of the control link (C++17): builds authenticated PUT /control request lines
// and parses the firmware's reply lines. The link is defined in protocol/control/control_spec.json
// (see docs/protocol-control.md); this codec, the Python one (rgbd_protocol.control) and the
// firmware core all replay protocol/control/vectors/control_vectors.json. Pure functions and value
// types; SequenceCounter is not thread-safe (one per sending thread).
#ifndef RGBD_CONTROL_CLIENT_CODEC_H_
#define RGBD_CONTROL_CLIENT_CODEC_H_

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "rgbd_control/control_spec_generated.h"
#include "rgbd_control/control_types_generated.hpp"

namespace rgbd_control {

// Constants (schema version, ranges, kMaxRequestBytes, Status) and the value types Key and Reply
// are generated from control_spec.json (protocol/control/tools/gen_control.py); the firmware's
// tighter hard limits are its own (firmware/core/limits.h) and are not repeated here.

/// Parses a 32-hex-digit key (the ground-station config's control_key_hex); nullopt if invalid.
std::optional<Key> parse_key_hex(std::string_view hex);

struct ControlCommand {
  uint32_t seq = 0;  ///< strictly increasing, >= 1
  bool arm = false;
  uint16_t roll_us = 1500;   ///< RC channel 1
  uint16_t pitch_us = 1500;  ///< RC channel 2
  uint16_t thr_us = 1000;    ///< RC channel 3
  uint16_t yaw_us = 1500;    ///< RC channel 4
};

/// The request line (without newline), or nullopt with *error set when a value is out of range.
std::optional<std::string> build_control_request(const Key& key, const ControlCommand& cmd,
                                                 std::string* error = nullptr);
/// "GET /status".
std::string build_status_request();

/// Parses one reply line ("<status> <json>", optional trailing newline); nullopt with *error set
/// on anything malformed (keys out of order, unknown status/state, values out of range, truncation)
/// and on a reply of another control-link version ("ver" != kControlLinkVersion: the firmware
/// speaks another layout; the error names both versions).
std::optional<Reply> parse_reply(std::string_view line, std::string* error = nullptr);

/// Strictly increasing sequence numbers; resume after the craft's last accepted one (reply.seq).
class SequenceCounter {
 public:
  explicit SequenceCounter(uint32_t start_after = 0) : last_(start_after) {}
  /// The next number, or nullopt when exhausted (2^32 - 1 used: provision a new key).
  std::optional<uint32_t> next() {
    if (last_ == UINT32_MAX) return std::nullopt;
    return ++last_;
  }

 private:
  uint32_t last_;
};

}  // namespace rgbd_control

#endif  // RGBD_CONTROL_CLIENT_CODEC_H_
