// Bounded text writer for replies: appends into a caller-owned buffer and never writes past its
// capacity (one byte is kept for the terminating NUL). Not thread-safe.
#ifndef FIRMWARE_CORE_TEXT_WRITER_H_
#define FIRMWARE_CORE_TEXT_WRITER_H_

#include <stddef.h>
#include <stdint.h>

namespace fw {

class TextWriter {
 public:
  /// `buf` must hold `cap` >= 1 bytes and outlive the writer.
  TextWriter(char* buf, size_t cap) : buf_(buf), cap_(cap) { buf_[0] = '\0'; }
  void str(const char* s) {
    while (*s != '\0') ch(*s++);
  }
  void ch(char c) {
    if (len_ + 1 < cap_) {
      buf_[len_++] = c;
      buf_[len_] = '\0';
    } else {
      truncated_ = true;
    }
  }
  void u32(uint32_t v) {
    if (v <= 0xFFFFU) {  // 16-bit division is ~4x faster than 32-bit on the ATmega
      u16(static_cast<uint16_t>(v));
      return;
    }
    char tmp[10];
    int n = 0;
    do {
      tmp[n++] = static_cast<char>('0' + v % 10U);
      v /= 10U;
    } while (v != 0U);
    while (n > 0) ch(tmp[--n]);
  }
  void u16(uint16_t v) {
    char tmp[5];
    int n = 0;
    do {
      tmp[n++] = static_cast<char>('0' + v % 10U);
      v = static_cast<uint16_t>(v / 10U);
    } while (v != 0U);
    while (n > 0) ch(tmp[--n]);
  }
  void i32(int32_t v) {
    if (v < 0) {
      ch('-');
      u32(static_cast<uint32_t>(-(v + 1)) + 1U);
    } else {
      u32(static_cast<uint32_t>(v));
    }
  }
  size_t length() const { return len_; }
  bool truncated() const { return truncated_; }

 private:
  char* buf_;
  size_t cap_;
  size_t len_ = 0;
  bool truncated_ = false;
};

}  // namespace fw

#endif  // FIRMWARE_CORE_TEXT_WRITER_H_
