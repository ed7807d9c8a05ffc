// Bounded line assembly for the bridge link; see line_assembler.h.
#include "line_assembler.h"

namespace fw {

LineEvent LineAssembler::feed(uint8_t byte, uint32_t now_ms) {
  if (complete_) {  // the previous line has been consumed by now
    complete_ = false;
    fill_ = 0;
    len_ = 0;
  }
  if (fill_ == 0 && !overflow_) first_byte_ms_ = now_ms;
  if (byte == '\n') {
    if (overflow_) {
      overflow_ = false;
      fill_ = 0;
      return LineEvent::kTooLong;
    }
    len_ = fill_;
    if (len_ > 0 && buf_[len_ - 1] == '\r') --len_;
    complete_ = true;
    return LineEvent::kLine;
  }
  if (overflow_) return LineEvent::kNone;
  if (fill_ >= sizeof(buf_)) {
    overflow_ = true;  // discard until the newline
    return LineEvent::kNone;
  }
  buf_[fill_++] = static_cast<char>(byte);
  return LineEvent::kNone;
}

LineEvent LineAssembler::poll(uint32_t now_ms) {
  const bool partial = (!complete_ && fill_ > 0) || overflow_;
  if (partial && static_cast<uint32_t>(now_ms - first_byte_ms_) >= kLineStallTimeoutMs) {
    fill_ = 0;
    overflow_ = false;
    return LineEvent::kStalled;
  }
  return LineEvent::kNone;
}

}  // namespace fw
