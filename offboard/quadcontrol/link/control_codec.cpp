// Control-link codec: see control_codec.hpp.
#include "link/control_codec.hpp"

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "rgbd_control/siphash24.h"

namespace rgbdquad::quadcontrol {

namespace {
constexpr const char* kFieldOrder[] = {"seq", "arm", "roll", "pitch", "thr", "yaw"};
constexpr const char* kReplyFields[] = {"err", "fw", "state", "seq", "out_us", "clamped",
                                        "att_mrad", "att_age_ms", "imu_raw", "imu_age_ms"};

template <std::size_t N>
bool read_ints(const nlohmann::json& j, const char* name, std::array<int, N>& out, std::string* error) {
  const auto& v = j[name];
  if (!v.is_array() || v.size() != N) {
    *error = std::string("reply field ") + name + " must be an array of " + std::to_string(N) + " integers";
    return false;
  }
  for (std::size_t i = 0; i < N; ++i) {
    if (!v[i].is_number_integer()) {
      *error = std::string("reply field ") + name + " must hold integers";
      return false;
    }
    out[i] = v[i].get<int>();
  }
  return true;
}

bool read_age(const nlohmann::json& j, const char* name, std::optional<std::uint32_t>& out, std::string* error) {
  const auto& v = j[name];
  if (v.is_null()) {
    out.reset();
    return true;
  }
  if (!v.is_number_unsigned() || v.get<std::uint64_t>() > 0xFFFFFFFFULL) {
    *error = std::string("reply field ") + name + " must be null or a u32";
    return false;
  }
  out = static_cast<std::uint32_t>(v.get<std::uint64_t>());
  return true;
}
}  // namespace

std::optional<ControlKey> parse_control_key(const std::string& hex, std::string* error) {
  if (hex.size() != 32) {
    *error = "control key must be 32 hex digits (16 bytes), got " + std::to_string(hex.size()) + " characters";
    return std::nullopt;
  }
  ControlKey key{};
  for (std::size_t i = 0; i < 16; ++i) {
    unsigned v = 0;
    for (int k = 0; k < 2; ++k) {
      const char c = hex[2 * i + k];
      unsigned d;
      if (c >= '0' && c <= '9') d = c - '0';
      else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
      else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
      else {
        *error = "control key: not a hex digit";
        return std::nullopt;
      }
      v = v * 16 + d;
    }
    key[i] = static_cast<std::uint8_t>(v);
  }
  return key;
}

std::optional<ControlSpec> load_control_spec(const std::string& spec_path, std::string* error) {
  std::ifstream in(spec_path);
  if (!in) {
    *error = "cannot read control spec " + spec_path;
    return std::nullopt;
  }
  try {
    const auto j = nlohmann::json::parse(in);
    ControlSpec spec;
    std::map<std::string, nlohmann::json> ranges;
    for (const auto& f : j.at("control_fields")) ranges[f.at("name").get<std::string>()] = f.at("range");
    for (const char* name : kFieldOrder) {
      if (!ranges.count(name)) {
        *error = std::string("control spec lacks field ") + name;
        return std::nullopt;
      }
    }
    spec.seq_min = ranges["seq"][0].get<std::uint32_t>();
    spec.seq_max = ranges["seq"][1].get<std::uint32_t>();
    auto pwm = [&](const char* name) {
      const auto lo = ranges[name][0].get<std::uint16_t>();
      const auto hi = ranges[name][1].get<std::uint16_t>();
      return PwmRange{lo, static_cast<std::uint16_t>((lo + hi) / 2), hi};
    };
    spec.pwm = PwmRanges{pwm("roll"), pwm("pitch"), pwm("yaw"), pwm("thr")};
    spec.control_path = j.at("routes").at("control").at("path").get<std::string>();
    spec.status_path = j.at("routes").at("status").at("path").get<std::string>();
    return spec;
  } catch (const std::exception& e) {
    *error = "control spec " + spec_path + ": " + e.what();
    return std::nullopt;
  }
}

std::optional<std::string> build_control_target(const ControlSpec& spec, const ControlKey& key,
                                                const ControlFields& f, std::string* error) {
  const std::uint32_t values[] = {f.seq, f.arm ? 1u : 0u, f.roll_us, f.pitch_us, f.thr_us, f.yaw_us};
  const PwmRange* pwm[] = {nullptr, nullptr, &spec.pwm.roll, &spec.pwm.pitch, &spec.pwm.throttle, &spec.pwm.yaw};
  if (f.seq < spec.seq_min || f.seq > spec.seq_max) {
    *error = "seq outside the spec range";
    return std::nullopt;
  }
  for (int i = 2; i < 6; ++i) {
    if (values[i] < pwm[i]->min_us || values[i] > pwm[i]->max_us) {
      *error = std::string(kFieldOrder[i]) + " outside the spec range";
      return std::nullopt;
    }
  }
  std::ostringstream target;
  target << spec.control_path << '?';
  for (int i = 0; i < 6; ++i) target << (i ? "&" : "") << kFieldOrder[i] << '=' << values[i];
  const std::string signed_part = "PUT " + target.str();
  const std::uint64_t tag = rgbd_control::siphash24(
      key.data(), reinterpret_cast<const std::uint8_t*>(signed_part.data()), signed_part.size());
  static const char* kHex = "0123456789abcdef";
  std::string mac;
  for (int i = 0; i < 8; ++i) {
    const auto byte = static_cast<std::uint8_t>(tag >> (8 * i));
    mac += kHex[byte >> 4];
    mac += kHex[byte & 15];
  }
  return target.str() + "&mac=" + mac;
}

std::optional<ControlReply> parse_control_reply(int status, const std::string& body, std::string* error) {
  const auto j = nlohmann::json::parse(body, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    *error = "reply body is not a JSON object";
    return std::nullopt;
  }
  for (const char* k : kReplyFields) {
    if (!j.contains(k)) {
      *error = std::string("reply lacks ") + k;
      return std::nullopt;
    }
  }
  if (!j["err"].is_string() || !j["fw"].is_string() || !j["state"].is_string() ||
      !j["seq"].is_number_unsigned() || !j["clamped"].is_number_integer()) {
    *error = "reply field of the wrong type";
    return std::nullopt;
  }
  ControlReply r;
  r.status = status;
  r.err = j["err"].get<std::string>();
  r.fw = j["fw"].get<std::string>();
  r.state = j["state"].get<std::string>();
  r.seq = j["seq"].get<std::uint32_t>();
  r.clamped = j["clamped"].get<int>();
  if (!read_ints(j, "out_us", r.out_us, error) || !read_ints(j, "att_mrad", r.att_mrad, error) ||
      !read_ints(j, "imu_raw", r.imu_raw, error) || !read_age(j, "att_age_ms", r.att_age_ms, error) ||
      !read_age(j, "imu_age_ms", r.imu_age_ms, error)) {
    return std::nullopt;
  }
  return r;
}

}  // namespace rgbdquad::quadcontrol
