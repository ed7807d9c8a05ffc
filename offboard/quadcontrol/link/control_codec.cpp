// Control-link adapter: see control_codec.hpp. Encoding, MAC and reply validation are
// protocol/control's rgbd_control_client_codec; this file adds the spec-derived ranges and routes.
#include "link/control_codec.hpp"

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "rgbd_control/client_codec.h"

namespace rgbdquad::quadcontrol {

namespace {
constexpr const char* kFieldOrder[] = {"seq", "arm", "roll", "pitch", "thr", "yaw"};
constexpr const char* kRequestMethod = "PUT ";
}  // namespace

std::optional<rgbd_control::Key> parse_control_key(const std::string& hex, std::string* error) {
  const auto key = rgbd_control::parse_key_hex(hex);
  if (!key) {
    *error = "control key must be 32 hex digits (16 bytes), got \"" + hex.substr(0, 40) + "\"";
    return std::nullopt;
  }
  return *key;
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
    for (const auto& f : j.at("control_fields"))
      ranges[f.at("name").get<std::string>()] = f.at("range");
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

std::optional<std::string> build_control_target(const ControlSpec& spec,
                                                const rgbd_control::Key& key,
                                                const ControlFields& f, std::string* error) {
  const std::uint32_t values[] = {f.seq,      f.arm ? 1u : 0u, f.roll_us,
                                  f.pitch_us, f.thr_us,        f.yaw_us};
  const PwmRange* pwm[] = {
      nullptr, nullptr, &spec.pwm.roll, &spec.pwm.pitch, &spec.pwm.throttle, &spec.pwm.yaw};
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
  rgbd_control::ControlCommand cmd;
  cmd.seq = f.seq;
  cmd.arm = f.arm;
  cmd.roll_us = f.roll_us;
  cmd.pitch_us = f.pitch_us;
  cmd.thr_us = f.thr_us;
  cmd.yaw_us = f.yaw_us;
  auto line = rgbd_control::build_control_request(key, cmd, error);
  if (!line) return std::nullopt;
  // The shared codec returns the request line "PUT <target>"; Beast wants the target alone.
  if (line->rfind(kRequestMethod, 0) != 0 ||
      line->compare(4, spec.control_path.size(), spec.control_path) != 0) {
    *error = "control request does not match the spec's route " + spec.control_path;
    return std::nullopt;
  }
  return line->substr(4);
}

std::optional<rgbd_control::Reply> parse_control_reply(int status, const std::string& body,
                                                       std::string* error) {
  // The bridge turns the firmware's reply line "<status> <json>" into an HTTP status and body;
  // rebuild the line and let the shared codec validate it exactly as the golden vectors do.
  return rgbd_control::parse_reply(std::to_string(status) + " " + body, error);
}

}  // namespace rgbdquad::quadcontrol
