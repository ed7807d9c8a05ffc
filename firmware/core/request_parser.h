// Strict parser of one request line from the WiFi bridge (see docs/protocol-control.md):
//   PUT /control?seq=<u32>&arm=<0|1>&roll=<us>&pitch=<us>&thr=<us>&yaw=<us>&mac=<16 lowercase hex>
//   GET /status
// Fields must appear exactly in this order, decimal without sign or leading zeros, only printable
// ASCII. The parser only checks syntax and records values (saturating, with an overflow flag); MAC,
// sequence and range checks are the Controller's. It reads at most `len` bytes and never writes
// outside the ParsedRequest: no input can overflow anything. Pure function, re-entrant.
#ifndef FIRMWARE_CORE_REQUEST_PARSER_H_
#define FIRMWARE_CORE_REQUEST_PARSER_H_

#include <stddef.h>
#include <stdint.h>

#include "status.h"

namespace fw {

enum class RequestKind : uint8_t { kInvalid, kControl, kStatus };

struct ParsedRequest {
  RequestKind kind = RequestKind::kInvalid;
  Status status = Status::kMalformed;  ///< kOk when the syntax is valid, else the error to reply
  uint32_t seq = 0;
  uint32_t arm = 0;
  uint32_t channel_us[4] = {0, 0, 0, 0};  ///< ArduPilot order: roll, pitch, throttle, yaw
  bool value_overflow = false;            ///< a decimal did not fit in 32 bits
  size_t signed_len = 0;                  ///< bytes [0, signed_len) are covered by the MAC
  uint8_t mac[8] = {0, 0, 0, 0, 0, 0, 0, 0};
};

/// Parses `len` bytes at `line` (no newline). Never reads past `len`.
ParsedRequest parse_request(const char* line, size_t len);

}  // namespace fw

#endif  // FIRMWARE_CORE_REQUEST_PARSER_H_
