// Assembles request lines from the bridge's byte stream with a fixed buffer: a line ends at '\n'
// (a preceding '\r' is dropped). A line that exceeds kMaxRequestBytes is reported (kTooLong, reply
// 414) at once, on its first excess byte - not at its newline, which may never come - and the rest
// of it is then discarded silently up to its newline. A line that gets no byte for
// kLineStallTimeoutMs is discarded: reported (kStalled, reply 408) if it was a partial request,
// silently if it was the rest of an over-long line (that line was already answered 414). A
// kLineCutMarker byte (core/rx_ring.h: the RX ring was full and dropped the rest of the line) ends
// the line and discards it whole (kDropped, no reply): a line that lost bytes is never parsed.
// Exactly one event is reported per line. Time is passed in. Not thread-safe: feed from one
// context (the main loop).
#ifndef FIRMWARE_CORE_LINE_ASSEMBLER_H_
#define FIRMWARE_CORE_LINE_ASSEMBLER_H_

#include <stddef.h>
#include <stdint.h>

#include "limits.h"
#include "rx_ring.h"

namespace fw {

enum class LineEvent : uint8_t {
  kNone,     ///< nothing complete yet
  kLine,     ///< a complete line is in line()/length()
  kTooLong,  ///< the line exceeded kMaxRequestBytes; its rest is being discarded (reply 414)
  kStalled,  ///< an incomplete line got no byte for kLineStallTimeoutMs and was discarded (reply
             ///< 408)
  kDropped,  ///< the line lost bytes in the RX ring (kLineCutMarker) and was discarded (no reply)
};

class LineAssembler {
 public:
  /// Adds one received byte at time now_ms.
  LineEvent feed(uint8_t byte, uint32_t now_ms);
  /// Checks for a stalled partial line at now_ms (call regularly).
  LineEvent poll(uint32_t now_ms);
  /// True while the rest of an over-long line (already reported) is being discarded: feeding these
  /// bytes never produces an event nor touches line(), so the caller may drain them at any time,
  /// e.g. while the 414 reply is still being sent.
  bool discarding() const { return discarding_; }
  /// The last complete line (valid after kLine until the next feed()).
  const char* line() const { return buf_; }
  size_t length() const { return len_; }

 private:
  char buf_[kMaxRequestBytes];
  size_t len_ = 0;
  size_t fill_ = 0;
  bool discarding_ = false;
  bool complete_ = false;
  uint32_t last_byte_ms_ = 0;
};

}  // namespace fw

#endif  // FIRMWARE_CORE_LINE_ASSEMBLER_H_
