// Assembles request lines from the bridge's byte stream with a fixed buffer: a line ends at '\n'
// (a preceding '\r' is dropped). Over-long lines are discarded up to their newline and reported
// once; a line left incomplete for kLineStallTimeoutMs is discarded and reported (a truncated
// request). Time is passed in. Not thread-safe: feed from one context (the main loop).
#ifndef FIRMWARE_CORE_LINE_ASSEMBLER_H_
#define FIRMWARE_CORE_LINE_ASSEMBLER_H_

#include <stddef.h>
#include <stdint.h>

#include "limits.h"

namespace fw {

enum class LineEvent : uint8_t {
  kNone,      ///< nothing complete yet
  kLine,      ///< a complete line is in line()/length()
  kTooLong,   ///< a line exceeded kMaxRequestBytes and was discarded (reply 414)
  kStalled,   ///< an incomplete line timed out and was discarded (reply 408)
};

class LineAssembler {
 public:
  /// Adds one received byte at time now_ms.
  LineEvent feed(uint8_t byte, uint32_t now_ms);
  /// Checks for a stalled partial line at now_ms (call regularly).
  LineEvent poll(uint32_t now_ms);
  /// The last complete line (valid after kLine until the next feed()).
  const char* line() const { return buf_; }
  size_t length() const { return len_; }

 private:
  char buf_[kMaxRequestBytes];
  size_t len_ = 0;
  size_t fill_ = 0;
  bool overflow_ = false;
  bool complete_ = false;
  uint32_t first_byte_ms_ = 0;
};

}  // namespace fw

#endif  // FIRMWARE_CORE_LINE_ASSEMBLER_H_
