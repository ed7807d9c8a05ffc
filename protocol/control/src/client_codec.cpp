// Ground-station control codec; see client_codec.h.
#include "rgbd_control/client_codec.h"

#include <algorithm>
#include <charconv>

#include "rgbd_control/siphash24.h"

namespace rgbd_control {
namespace {

bool fail(std::string* error, const std::string& msg) {
  if (error != nullptr) *error = msg;
  return false;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// Strict left-to-right reader of the reply's fixed layout.
class Reader {
 public:
  explicit Reader(std::string_view s) : s_(s) {}
  bool lit(std::string_view l) {
    if (s_.substr(i_, l.size()) != l) return false;
    i_ += l.size();
    return true;
  }
  bool integer(int64_t lo, int64_t hi, int64_t* out) {
    const char* b = s_.data() + i_;
    const char* e = s_.data() + s_.size();
    int64_t v = 0;
    auto [p, ec] = std::from_chars(b, e, v);
    if (ec != std::errc() || p == b || v < lo || v > hi) return false;
    i_ += static_cast<size_t>(p - b);
    *out = v;
    return true;
  }
  bool word(std::string* out) {  // a JSON string without escapes
    if (!lit("\"")) return false;
    const size_t end = s_.find('"', i_);
    if (end == std::string_view::npos) return false;
    const std::string_view w = s_.substr(i_, end - i_);
    if (w.find('\\') != std::string_view::npos) return false;
    *out = std::string(w);
    i_ = end + 1;
    return true;
  }
  template <typename T, size_t N>
  bool int_array(int64_t lo, int64_t hi, std::array<T, N>* out) {
    if (!lit("[")) return false;
    for (size_t k = 0; k < N; ++k) {
      int64_t v = 0;
      if ((k > 0 && !lit(",")) || !integer(lo, hi, &v)) return false;
      (*out)[k] = static_cast<T>(v);
    }
    return lit("]");
  }
  bool opt_u32(std::optional<uint32_t>* out) {
    if (lit("null")) {
      out->reset();
      return true;
    }
    int64_t v = 0;
    if (!integer(0, UINT32_MAX, &v)) return false;
    *out = static_cast<uint32_t>(v);
    return true;
  }
  bool at_end() {
    lit("\r");
    lit("\n");
    return i_ == s_.size();
  }

 private:
  std::string_view s_;
  size_t i_ = 0;
};

}  // namespace

std::optional<Key> parse_key_hex(std::string_view hex) {
  if (hex.size() != 32) return std::nullopt;
  Key k{};
  for (size_t i = 0; i < 16; ++i) {
    const int hi = hex_value(hex[2 * i]);
    const int lo = hex_value(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    k[i] = static_cast<uint8_t>(hi * 16 + lo);
  }
  return k;
}

std::optional<std::string> build_control_request(const Key& key, const ControlCommand& cmd,
                                                 std::string* error) {
  if (cmd.seq == 0) {
    fail(error, "seq must be >= 1");
    return std::nullopt;
  }
  const struct {
    const char* name;
    uint16_t v;
  } ch[4] = {
      {"roll", cmd.roll_us}, {"pitch", cmd.pitch_us}, {"thr", cmd.thr_us}, {"yaw", cmd.yaw_us}};
  std::string line = std::string(kControlMethod) + " " + kControlPath +
                     "?seq=" + std::to_string(cmd.seq) + "&arm=" + (cmd.arm ? "1" : "0");
  for (const auto& c : ch) {
    if (c.v < kChannelMinUs || c.v > kChannelMaxUs) {
      fail(error, std::string(c.name) + "=" + std::to_string(c.v) + " outside [" +
                      std::to_string(kChannelMinUs) + ", " + std::to_string(kChannelMaxUs) +
                      "] us");
      return std::nullopt;
    }
    line += std::string("&") + c.name + "=" + std::to_string(c.v);
  }
  uint8_t tag[kSipHashTagBytes];
  siphash24_tag_bytes(
      siphash24(key.data(), reinterpret_cast<const uint8_t*>(line.data()), line.size()), tag);
  static const char* kDigits = "0123456789abcdef";
  line += "&mac=";
  for (uint8_t b : tag) {
    line += kDigits[b >> 4];
    line += kDigits[b & 15];
  }
  return line;
}

std::string build_status_request() { return std::string(kStatusMethod) + " " + kStatusPath; }

std::optional<Reply> parse_reply(std::string_view line, std::string* error) {
  Reader r(line);
  Reply out;
  int64_t v = 0;
  if (!r.integer(100, 599, &v) || !r.lit(" ")) {
    fail(error, "reply does not start with '<status> '");
    return std::nullopt;
  }
  out.status = static_cast<int>(v);
  if (!is_status_code(out.status)) {
    fail(error, "unknown status " + std::to_string(out.status));
    return std::nullopt;
  }
  const char* reason = status_reason(static_cast<Status>(out.status));
  // The version first: a peer of another version may have changed everything after it.
  if (!r.lit("{\"ver\":") || !r.integer(0, 255, &v)) {
    fail(error, "reply does not start with the control-link version (\"ver\")");
    return std::nullopt;
  }
  out.ver = static_cast<uint8_t>(v);
  if (out.ver != kControlLinkVersion) {
    fail(error, "control-link version " + std::to_string(out.ver) + " from the firmware, " +
                    std::to_string(kControlLinkVersion) +
                    " here: update the firmware or the ground station");
    return std::nullopt;
  }
  const bool ok = r.lit(",\"err\":") && r.word(&out.err) && r.lit(",\"fw\":") && r.word(&out.fw) &&
                  r.lit(",\"state\":") && r.word(&out.state) && r.lit(",\"seq\":") &&
                  r.integer(0, UINT32_MAX, &v) && ((out.seq = static_cast<uint32_t>(v)), true) &&
                  r.lit(",\"out_us\":") && r.int_array(0, 65535, &out.out_us) &&
                  r.lit(",\"clamped\":") && r.integer(0, 15, &v) &&
                  ((out.clamped = static_cast<uint8_t>(v)), true) && r.lit(",\"att_mrad\":") &&
                  r.int_array(INT16_MIN, INT16_MAX, &out.att_mrad) && r.lit(",\"att_age_ms\":") &&
                  r.opt_u32(&out.att_age_ms) && r.lit(",\"imu_raw\":") &&
                  r.int_array(INT16_MIN, INT16_MAX, &out.imu_raw) && r.lit(",\"imu_age_ms\":") &&
                  r.opt_u32(&out.imu_age_ms) && r.lit("}") && r.at_end();
  if (!ok) {
    fail(error, "reply body malformed or truncated");
    return std::nullopt;
  }
  if (out.err != reason) {
    fail(error, "reason '" + out.err + "' does not match status " + std::to_string(out.status));
    return std::nullopt;
  }
  if (std::find(kReplyStates.begin(), kReplyStates.end(), out.state) == kReplyStates.end()) {
    fail(error, "unknown state '" + out.state + "'");
    return std::nullopt;
  }
  return out;
}

}  // namespace rgbd_control
