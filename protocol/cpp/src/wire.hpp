// Internal: explicit little-endian writer and bounds-checked reader over a byte buffer.
// The reader never reads past `size`; a short read sets truncated() and returns zeros, so decoders
// parse structurally to the end and report the first structural problem, then validate values.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace rgbdquad::protocol::wire {

class Writer {
 public:
  explicit Writer(std::vector<std::uint8_t>& out) : out_(out) {}
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { put_le(v, 2); }
  void u32(std::uint32_t v) { put_le(v, 4); }
  void u64(std::uint64_t v) { put_le(v, 8); }
  void f64(double v) {
    std::uint64_t bits = 0;
    static_assert(sizeof bits == sizeof v);
    std::memcpy(&bits, &v, sizeof bits);  // IEEE-754 bit pattern of one scalar, then LE bytes
    u64(bits);
  }
  void raw(const std::uint8_t* data, std::size_t size) {
    if (size > 0) out_.insert(out_.end(), data, data + size);
  }

 private:
  void put_le(std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t>& out_;
};

class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(get_le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(get_le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(get_le(4)); }
  std::uint64_t u64() { return get_le(8); }
  double f64() {
    const std::uint64_t bits = u64();
    double v = 0.0;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  /// Pointer to `count` bytes, or nullptr (and truncated) when fewer remain.
  const std::uint8_t* take(std::size_t count) {
    if (failed() || count > remaining()) {
      truncated_ = true;
      return nullptr;
    }
    const std::uint8_t* p = data_ + pos_;
    pos_ += count;
    return p;
  }
  std::size_t remaining() const { return size_ - pos_; }
  bool truncated() const { return truncated_; }
  bool failed() const { return truncated_ || !length_error_.empty(); }
  /// A length prefix above its limit: structural, stops parsing (nothing more can be trusted).
  void length_error(const std::string& what) {
    if (!failed()) length_error_ = what;
  }
  const std::string& length_error_detail() const { return length_error_; }

 private:
  std::uint64_t get_le(int bytes) {
    const std::uint8_t* p = take(static_cast<std::size_t>(bytes));
    if (p == nullptr) return 0;
    std::uint64_t v = 0;
    for (int i = 0; i < bytes; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
    return v;
  }
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  bool truncated_ = false;
  std::string length_error_;
};

}  // namespace rgbdquad::protocol::wire
