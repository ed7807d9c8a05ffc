// Strict request-line parser; see request_parser.h for the grammar.
#include "request_parser.h"

namespace fw {
namespace {

/// Cursor over a bounded byte range; every read checks the bound.
class Cursor {
 public:
  Cursor(const char* p, size_t n) : p_(p), n_(n) {}
  bool at_end() const { return i_ >= n_; }
  size_t pos() const { return i_; }
  /// Consumes `lit` if the input continues with it.
  bool take(const char* lit) {
    size_t j = 0;
    while (lit[j] != '\0') {
      if (i_ + j >= n_ || p_[i_ + j] != lit[j]) return false;
      ++j;
    }
    i_ += j;
    return true;
  }
  /// Decimal without sign or leading zeros; up to 10 digits; saturates at UINT32_MAX with overflow.
  bool take_decimal(uint32_t* out, bool* overflow) {
    size_t digits = 0;
    uint32_t v = 0;
    bool saturated = false;
    while (i_ < n_ && p_[i_] >= '0' && p_[i_] <= '9') {
      if (digits == 1 && p_[i_ - 1] == '0') return false;  // leading zero
      if (digits == 10) return false;                      // longer than any u32
      const uint32_t d = static_cast<uint32_t>(p_[i_] - '0');
      if (saturated || v > (0xFFFFFFFFUL - d) / 10UL) {
        saturated = true;
        v = 0xFFFFFFFFUL;
      } else {
        v = v * 10UL + d;
      }
      ++i_;
      ++digits;
    }
    if (saturated) *overflow = true;
    *out = v;
    return digits > 0;
  }
  bool take_hex_bytes(uint8_t* out, size_t count) {
    for (size_t b = 0; b < count; ++b) {
      uint8_t byte = 0;
      for (int nib = 0; nib < 2; ++nib) {
        if (i_ >= n_) return false;
        const char c = p_[i_++];
        uint8_t v;
        if (c >= '0' && c <= '9') {
          v = static_cast<uint8_t>(c - '0');
        } else if (c >= 'a' && c <= 'f') {
          v = static_cast<uint8_t>(c - 'a' + 10);
        } else {
          return false;
        }
        byte = static_cast<uint8_t>((byte << 4) | v);
      }
      out[b] = byte;
    }
    return true;
  }

 private:
  const char* p_;
  size_t n_;
  size_t i_ = 0;
};

bool all_printable(const char* line, size_t len) {
  for (size_t i = 0; i < len; ++i) {
    if (line[i] < 0x20 || line[i] > 0x7E) return false;
  }
  return true;
}

/// Field names of the control route, in wire order, after "seq" and "arm".
const char* const kChannelKeys[4] = {"&roll=", "&pitch=", "&thr=", "&yaw="};

}  // namespace

ParsedRequest parse_request(const char* line, size_t len) {
  ParsedRequest r;
  if (line == nullptr || len == 0 || !all_printable(line, len)) return r;  // 400
  Cursor c(line, len);
  // Method: an upper-case token then one space.
  bool is_put = false;
  bool is_get = false;
  if (c.take("PUT ")) {
    is_put = true;
  } else if (c.take("GET ")) {
    is_get = true;
  } else {
    size_t i = 0;
    while (i < len && line[i] >= 'A' && line[i] <= 'Z') ++i;
    if (i > 0 && i < len && line[i] == ' ') r.status = Status::kBadMethod;
    return r;
  }
  if (c.take("/control")) {
    if (!is_put) {
      r.status = Status::kBadMethod;
      return r;
    }
    r.kind = RequestKind::kControl;
    if (!c.take("?seq=") || !c.take_decimal(&r.seq, &r.value_overflow)) return r;
    if (!c.take("&arm=") || !c.take_decimal(&r.arm, &r.value_overflow)) return r;
    for (int ch = 0; ch < 4; ++ch) {
      if (!c.take(kChannelKeys[ch]) || !c.take_decimal(&r.channel_us[ch], &r.value_overflow)) {
        return r;
      }
    }
    r.signed_len = c.pos();
    if (!c.take("&mac=") || !c.take_hex_bytes(r.mac, sizeof(r.mac)) || !c.at_end()) return r;
    r.status = Status::kOk;
    return r;
  }
  if (c.take("/status")) {
    if (!is_get) {
      r.status = Status::kBadMethod;
      return r;
    }
    if (!c.at_end()) return r;
    r.kind = RequestKind::kStatus;
    r.status = Status::kOk;
    return r;
  }
  if (c.take("/")) r.status = Status::kNoRoute;
  (void)is_get;
  return r;
}

}  // namespace fw
