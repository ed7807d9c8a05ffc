// C++ ground-station side of the control link (protocol/control/control_spec.json,
// docs/protocol-control.md): builds the authenticated "PUT
// /control?seq=..&arm=..&roll=..&pitch=..&thr=..&yaw=..&mac=.." target and parses the "<status>
// <json>" reply. A thin adapter over protocol/control's shared C++ codec
// (rgbd_control_client_codec: request line, SipHash-2-4 MAC, strict reply parsing) that adds the
// spec's ranges and routes, taken from the constants gen_control.py generates from it
// (rgbd_control/control_spec_generated.h: compiled in, no spec file is read at run time), never
// redefined here. Proven against protocol/control/vectors/control_vectors.json and the spec file
// itself in tests/control_codec_test.cpp. Pure functions; thread-safe.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/stick_mapping.hpp"
#include "rgbd_control/control_types_generated.hpp"

namespace rgbdquad::quadcontrol {

// The key and reply types are the control link's generated ones (rgbd_control::Key,
// rgbd_control::Reply from protocol/control/control_spec.json); nothing is mirrored here.

/// Parses 32 hex digits into a key; nullopt (error set) otherwise.
std::optional<rgbd_control::Key> parse_control_key(const std::string& hex, std::string* error);

/// The field ranges ("control_fields") and routes of control_spec.json.
struct ControlSpec {
  std::uint32_t seq_min = 0, seq_max = 0;
  PwmRanges pwm;             ///< neutral = middle of each range (RC stick centre)
  std::string control_path;  ///< "/control"
  std::string status_path;   ///< "/status"
};

/// The spec as generated into rgbd_control/control_spec_generated.h: the one the firmware and the
/// shared codec are built with (pytest's gen_control.py --check keeps the header equal to the
/// spec file; tests/control_codec_test.cpp compares this value with the file).
ControlSpec generated_control_spec();

struct ControlFields {
  std::uint32_t seq = 0;
  bool arm = false;
  std::uint16_t roll_us = 0, pitch_us = 0, thr_us = 0, yaw_us = 0;
};

/// HTTP target (path + query, MAC last) of an authenticated PUT /control. The MAC covers
/// "PUT <target before &mac=>". Fails (error set) when a field is outside the spec's range.
std::optional<std::string> build_control_target(const ControlSpec& spec,
                                                const rgbd_control::Key& key,
                                                const ControlFields& fields, std::string* error);

/// Parses the HTTP status and JSON body of a reply; nullopt (error set) when malformed or of
/// another control-link version.
std::optional<rgbd_control::Reply> parse_control_reply(int status, const std::string& json_body,
                                                       std::string* error);

}  // namespace rgbdquad::quadcontrol
