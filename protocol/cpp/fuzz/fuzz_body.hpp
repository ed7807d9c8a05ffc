// Shared body of the per-message libFuzzer targets: decode the input as one body of a message type;
// whatever decodes must re-encode (encode() accepts it) to exactly the input bytes, so the decoder
// and the encoder agree on every accepted message. Any crash, sanitizer report or abort fails.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "rgbdquad/protocol/codec.hpp"

namespace rgbdquad::protocol::fuzz {

inline int fuzz_body(MessageType type, const std::uint8_t* data, std::size_t size) {
  const BodyResult decoded = decode_body(static_cast<std::uint8_t>(type), data, size);
  if (!decoded.ok()) {
    if (decoded.error == DecodeError::kNone) std::abort();  // failure without a reason
    return 0;
  }
  if (message_type(*decoded.message) != type) std::abort();
  const EncodeResult again = encode_body(*decoded.message);
  if (!again.ok() || again.bytes.size() != size ||
      (size > 0 && std::memcmp(again.bytes.data(), data, size) != 0)) {
    std::abort();  // decoder accepted what the encoder refuses or writes differently
  }
  return 0;
}

}  // namespace rgbdquad::protocol::fuzz
