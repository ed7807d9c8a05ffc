// Shared body of the per-message libFuzzer targets: decode the input as one body of a message type,
// in every envelope version a decoder accepts (the current one and the older ones still decoded);
// whatever decodes must re-encode in that version (encode() accepts it) to exactly the input bytes,
// so the decoder and the encoder agree on every accepted message of every version. Any crash,
// sanitizer report or abort fails.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "rgbdquad/protocol/codec.hpp"

namespace rgbdquad::protocol::fuzz {

inline void fuzz_body_version(MessageType type, const std::uint8_t* data, std::size_t size,
                              unsigned version) {
  const BodyResult decoded = decode_body(static_cast<std::uint8_t>(type), data, size, version);
  if (!decoded.ok()) {
    if (decoded.error == DecodeError::kNone) std::abort();  // failure without a reason
    return;
  }
  if (message_type(*decoded.message) != type) std::abort();
  const EncodeResult again = encode_body(*decoded.message, version);
  if (!again.ok() || again.bytes.size() != size ||
      (size > 0 && std::memcmp(again.bytes.data(), data, size) != 0)) {
    std::abort();  // decoder accepted what the encoder refuses or writes differently
  }
}

inline int fuzz_body(MessageType type, const std::uint8_t* data, std::size_t size) {
  for (unsigned v = kOldestDecodedProtocolVersion; v <= kProtocolVersion; ++v)
    fuzz_body_version(type, data, size, v);
  return 0;
}

}  // namespace rgbdquad::protocol::fuzz
