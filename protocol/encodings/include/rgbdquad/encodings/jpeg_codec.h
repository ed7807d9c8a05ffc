// JPEG compression of RGB8 images through libjpeg-turbo's TurboJPEG API (lossy; the wire contract
// says an RGB payload with the JPEG encoding is one baseline JFIF image of the header's size).
//
// Thread safety: each JpegEncoder/JpegDecoder owns one TurboJPEG handle and must be used by one
// thread at a time; use one instance per thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rgbdquad::encodings {

class JpegEncoder {
 public:
  // quality 1..100; chroma 4:2:0 subsampling (what the Kinect's Bayer RGB can resolve anyway).
  // Throws std::runtime_error if TurboJPEG cannot be initialised or quality is out of range
  // (start-up boundary).
  explicit JpegEncoder(int quality);
  ~JpegEncoder();
  JpegEncoder(const JpegEncoder&) = delete;
  JpegEncoder& operator=(const JpegEncoder&) = delete;

  // rgb: width*height*3 bytes, row-major. Returns nullopt (and error) if TurboJPEG fails.
  std::optional<std::vector<std::uint8_t>> encode(const std::uint8_t* rgb, int width, int height,
                                                  std::string* error);

 private:
  void* handle_;
  int quality_;
};

class JpegDecoder {
 public:
  JpegDecoder();  // throws std::runtime_error if TurboJPEG cannot be initialised
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;

  // Decodes to RGB8; the image must be exactly expected_width x expected_height.
  std::optional<std::vector<std::uint8_t>> decode(const std::uint8_t* jpeg, std::size_t bytes,
                                                  int expected_width, int expected_height,
                                                  std::string* error);

 private:
  void* handle_;
};

}  // namespace rgbdquad::encodings
