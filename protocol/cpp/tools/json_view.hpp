// JSON view of every message, field names exactly as in protocol/spec/messages.json (enums by
// name, byte fields as lowercase hex, fixed arrays as lists). The Python codec produces the same
// view, which is how the cross-language tests compare decoded messages field by field.
// Not part of rgbd_protocol (which depends on the standard library only).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "rgbdquad/protocol/codec.hpp"

namespace rgbdquad::protocol {

/// {"type": "<MessageName>", "fields": {...}}
nlohmann::json to_json(const Message& message);

/// Inverse of to_json. Throws std::invalid_argument (naming the field) on a malformed view; value
/// rules are not checked here (encode() does that).
Message message_from_json(const nlohmann::json& view);

std::string to_hex(const std::uint8_t* data, std::size_t size);
/// Throws std::invalid_argument on odd length or a non-hex digit.
std::vector<std::uint8_t> from_hex(const std::string& hex);

}  // namespace rgbdquad::protocol
