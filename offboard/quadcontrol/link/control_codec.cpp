// Control-link adapter: see control_codec.hpp. Encoding, MAC and reply validation are
// protocol/control's rgbd_control_client_codec; this file adds the spec's ranges and routes (from
// the generated constants).
#include "link/control_codec.hpp"

#include <cstdint>

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

ControlSpec generated_control_spec() {
  using namespace rgbd_control;
  static_assert(kRollMaxUs <= UINT16_MAX && kPitchMaxUs <= UINT16_MAX && kThrMaxUs <= UINT16_MAX &&
                    kYawMaxUs <= UINT16_MAX,
                "PwmRange holds 16-bit pulse widths");
  const auto pwm = [](std::uint32_t lo, std::uint32_t hi) {
    return PwmRange{static_cast<std::uint16_t>(lo), static_cast<std::uint16_t>((lo + hi) / 2),
                    static_cast<std::uint16_t>(hi)};
  };
  ControlSpec spec;
  spec.seq_min = kSeqMin;
  spec.seq_max = kSeqMax;
  spec.pwm = PwmRanges{pwm(kRollMinUs, kRollMaxUs), pwm(kPitchMinUs, kPitchMaxUs),
                       pwm(kYawMinUs, kYawMaxUs), pwm(kThrMinUs, kThrMaxUs)};
  spec.control_path = kControlPath;
  spec.status_path = kStatusPath;
  return spec;
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
