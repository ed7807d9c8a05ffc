// PNG files as the TUM RGB-D benchmark stores them: 16-bit grey depth and 8-bit RGB colour, read
// with libpng (the capture library needs no OpenCV, so it also cross-builds for the ARM boards,
// where Debian 12's foreign-architecture OpenCV packages cannot be installed beside the host's).
// Pixel values are exactly the file's (no gamma or colour conversion), independent of host byte
// order.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rgbdquad::capture {

template <typename Pixel>
struct PngPixels {
  int width = 0;
  int height = 0;
  std::vector<Pixel> pixels;  // row-major; RGB: 3 bytes per pixel (R, G, B)
};

// A 16-bit single-channel PNG; anything else (8-bit, colour, unreadable) -> nullopt + *error.
std::optional<PngPixels<std::uint16_t>> read_png_gray16(const std::string& path,
                                                        std::string* error);

// Any PNG as 8-bit RGB: grey and palette images expanded, alpha dropped, 16-bit samples reduced to
// their high byte (as OpenCV's IMREAD_COLOR does). Unreadable -> nullopt + *error.
std::optional<PngPixels<std::uint8_t>> read_png_rgb8(const std::string& path, std::string* error);

}  // namespace rgbdquad::capture
