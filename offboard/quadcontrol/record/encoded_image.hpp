// An image as it came off the camera link, still encoded: the recorder stores these bytes as they
// are instead of re-encoding the decoded pixels (docs/recording.md "Images").
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace rgbdquad::quadcontrol {

struct EncodedImage {
  /// "jpeg" (RGB, one JFIF image); "rvl" or "zstd-delta" (depth, uint16 in the frame's depth units;
  /// protocol/encodings/README.md). Empty with `bytes` null: the frame came decoded only.
  std::string format;
  std::shared_ptr<const std::vector<std::uint8_t>>
      bytes;  ///< shared with the receiver, never written
  bool present() const { return bytes != nullptr && !bytes->empty(); }
};

}  // namespace rgbdquad::quadcontrol
