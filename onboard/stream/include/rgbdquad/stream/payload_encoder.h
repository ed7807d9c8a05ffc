// Turns a captured frame into the payload of a protocol Frame in the negotiated encoding
// (protocol/encodings codecs). One instance per sending thread (it owns a TurboJPEG handle).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/capture/frame.h"
#include "rgbdquad/protocol/messages.hpp"

namespace rgbdquad::encodings {
class JpegEncoder;
}

namespace rgbdquad::stream {

// Config names: "raw", "rvl", "zstd-delta" (depth); "raw", "jpeg" (RGB).
std::optional<protocol::Encoding> depth_encoding_from_string(const std::string& name);
std::optional<protocol::Encoding> rgb_encoding_from_string(const std::string& name);
std::string encoding_name(protocol::Encoding encoding);

class PayloadEncoder {
 public:
  // Throws std::invalid_argument if `encoding` cannot carry frames of this stream kind.
  PayloadEncoder(protocol::StreamKind kind, protocol::Encoding encoding, int jpeg_quality,
                 int zstd_level);
  ~PayloadEncoder();
  PayloadEncoder(const PayloadEncoder&) = delete;
  PayloadEncoder& operator=(const PayloadEncoder&) = delete;

  // Empty optional (and error) if the frame is of the other kind or the codec failed.
  std::optional<std::vector<std::uint8_t>> encode(const capture::SourceFrame& frame,
                                                  std::string* error);

 private:
  protocol::StreamKind kind_;
  protocol::Encoding encoding_;
  int zstd_level_;
  std::unique_ptr<encodings::JpegEncoder> jpeg_;
};

}  // namespace rgbdquad::stream
