// Bounded line assembly for the bridge link; see line_assembler.h.
#include "line_assembler.h"

namespace fw {

LineEvent LineAssembler::feed(uint8_t byte, uint32_t now_ms) {
  if (complete_) {  // the previous line has been consumed by now
    complete_ = false;
    fill_ = 0;
    len_ = 0;
  }
  last_byte_ms_ = now_ms;
  if (byte == kLineCutMarker) {  // ends an over-long line being discarded too (its '\n' was lost)
    discarding_ = false;
    fill_ = 0;
    return LineEvent::kDropped;
  }
  if (discarding_) {
    if (byte == '\n') discarding_ = false;  // end of the over-long line, already answered
    return LineEvent::kNone;
  }
  if (byte == '\n') {
    len_ = fill_;
    if (len_ > 0 && buf_[len_ - 1] == '\r') --len_;
    complete_ = true;
    return LineEvent::kLine;
  }
  if (fill_ >= sizeof(buf_)) {
    discarding_ = true;  // report now, then drop the rest up to the newline
    fill_ = 0;
    return LineEvent::kTooLong;
  }
  buf_[fill_++] = static_cast<char>(byte);
  return LineEvent::kNone;
}

LineEvent LineAssembler::poll(uint32_t now_ms) {
  const bool partial = discarding_ || (!complete_ && fill_ > 0);
  if (!partial || static_cast<uint32_t>(now_ms - last_byte_ms_) < kLineStallTimeoutMs) {
    return LineEvent::kNone;
  }
  const bool was_discarding = discarding_;
  discarding_ = false;
  fill_ = 0;
  return was_discarding ? LineEvent::kNone : LineEvent::kStalled;
}

}  // namespace fw
