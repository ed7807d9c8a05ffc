// libFuzzer target: the StreamChallenge body decoder (see fuzz_body.hpp for the property checked).
#include "fuzz_body.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return rgbdquad::protocol::fuzz::fuzz_body(rgbdquad::protocol::MessageType::kStreamChallenge,
                                             data, size);
}
