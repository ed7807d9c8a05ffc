// Reply status codes of the control link (HTTP status codes, so the bridge can forward them as-is).
// The numeric values and reason words are defined by protocol/control/control_spec.json.
#ifndef FIRMWARE_CORE_STATUS_H_
#define FIRMWARE_CORE_STATUS_H_

#include <stdint.h>

namespace fw {

enum class Status : uint16_t {
  kOk = 200,         ///< command applied (or status read)
  kMalformed = 400,  ///< syntax: unknown/missing/reordered field, bad digit, non-printable byte...
  kBadMac = 401,     ///< MAC does not match the fields under this craft's key
  kArmRefused =
      403,  ///< state forbids it: arm with throttle high, or re-arm without disarm after failsafe
  kNoRoute = 404,     ///< unknown path
  kBadMethod = 405,   ///< known path, wrong method
  kStalled = 408,     ///< request line left incomplete (truncated) for kLineStallTimeoutMs
  kStaleSeq = 409,    ///< sequence number not greater than the last accepted one (replay)
  kTooLong = 414,     ///< request line longer than kMaxRequestBytes
  kOutOfRange = 422,  ///< a value outside its protocol range
  kNoKey = 503,       ///< no valid key provisioned in EEPROM: every command is refused
};

/// Short reason word of a status (the reply's "err" field); never null.
inline const char* status_reason(Status s) {
  switch (s) {
    case Status::kOk:
      return "ok";
    case Status::kMalformed:
      return "malformed";
    case Status::kBadMac:
      return "bad_mac";
    case Status::kArmRefused:
      return "arm_refused";
    case Status::kNoRoute:
      return "no_route";
    case Status::kBadMethod:
      return "bad_method";
    case Status::kStalled:
      return "stalled";
    case Status::kStaleSeq:
      return "stale_seq";
    case Status::kTooLong:
      return "too_long";
    case Status::kOutOfRange:
      return "out_of_range";
    case Status::kNoKey:
      return "no_key";
  }
  return "unknown";
}

}  // namespace fw

#endif  // FIRMWARE_CORE_STATUS_H_
