// libFuzzer target: the StreamDecoder (envelope, resynchronisation, every body decoder) on
// arbitrary bytes fed in arbitrary chunks. Properties: never crashes; every error reports a reason;
// progress is always made (each next() either consumes bytes or asks for more), so it cannot hang;
// after the input ends it holds fewer bytes than one maximal frame.
#include <cstdint>
#include <cstdlib>

#include "rgbdquad/protocol/codec.hpp"

namespace proto = rgbdquad::protocol;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  // The first byte picks the chunk size (1..256) so splits at every offset get exercised.
  const std::size_t chunk = std::size_t{data[0]} + 1;
  ++data;
  --size;
  proto::StreamDecoder decoder;
  for (std::size_t off = 0; off < size; off += chunk) {
    const std::size_t n = size - off < chunk ? size - off : chunk;
    decoder.feed(data + off, n);
    for (;;) {
      const std::size_t before = decoder.buffered_bytes();
      const proto::DecodeResult r = decoder.next();
      if (r.status == proto::DecodeStatus::kNeedMoreBytes) break;
      if (r.status == proto::DecodeStatus::kError &&
          (r.error == proto::DecodeError::kNone || r.bytes_discarded == 0)) {
        std::abort();
      }
      if (decoder.buffered_bytes() >= before) std::abort();  // no progress: would hang
    }
  }
  return 0;
}
