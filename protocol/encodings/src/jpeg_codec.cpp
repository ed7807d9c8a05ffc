// JPEG encode/decode of RGB8 frames through TurboJPEG (libjpeg-turbo 2.1).
#include "rgbdquad/encodings/jpeg_codec.h"

#include <turbojpeg.h>

#include <stdexcept>

namespace rgbdquad::encodings {

JpegEncoder::JpegEncoder(int quality) : handle_(nullptr), quality_(quality) {
  if (quality < 1 || quality > 100) {
    throw std::runtime_error("JPEG quality must be 1..100, got " + std::to_string(quality));
  }
  handle_ = tjInitCompress();
  if (handle_ == nullptr) throw std::runtime_error("tjInitCompress failed");
}

JpegEncoder::~JpegEncoder() { tjDestroy(handle_); }

std::optional<std::vector<std::uint8_t>> JpegEncoder::encode(const std::uint8_t* rgb, int width,
                                                             int height, std::string* error) {
  if (width <= 0 || height <= 0) {
    if (error) *error = "jpeg: invalid image size";
    return std::nullopt;
  }
  // Compress into a preallocated buffer of the worst-case size so TurboJPEG never reallocates.
  std::vector<std::uint8_t> out(tjBufSize(width, height, TJSAMP_420));
  unsigned char* dst = out.data();
  unsigned long size = out.size();
  if (tjCompress2(handle_, rgb, width, 0, height, TJPF_RGB, &dst, &size, TJSAMP_420, quality_,
                  TJFLAG_NOREALLOC | TJFLAG_FASTDCT) != 0) {
    if (error) *error = std::string("jpeg: ") + tjGetErrorStr2(handle_);
    return std::nullopt;
  }
  out.resize(size);
  return out;
}

JpegDecoder::JpegDecoder() : handle_(tjInitDecompress()) {
  if (handle_ == nullptr) throw std::runtime_error("tjInitDecompress failed");
}

JpegDecoder::~JpegDecoder() { tjDestroy(handle_); }

std::optional<std::vector<std::uint8_t>> JpegDecoder::decode(const std::uint8_t* jpeg,
                                                             std::size_t bytes, int expected_width,
                                                             int expected_height,
                                                             std::string* error) {
  int width = 0;
  int height = 0;
  int subsampling = 0;
  int colorspace = 0;
  if (tjDecompressHeader3(handle_, jpeg, static_cast<unsigned long>(bytes), &width, &height,
                          &subsampling, &colorspace) != 0) {
    if (error) *error = std::string("jpeg header: ") + tjGetErrorStr2(handle_);
    return std::nullopt;
  }
  if (width != expected_width || height != expected_height) {
    if (error) {
      *error = "jpeg: image is " + std::to_string(width) + "x" + std::to_string(height) +
               ", header says " + std::to_string(expected_width) + "x" +
               std::to_string(expected_height);
    }
    return std::nullopt;
  }
  std::vector<std::uint8_t> out(static_cast<std::size_t>(width) * height * 3);
  if (tjDecompress2(handle_, jpeg, static_cast<unsigned long>(bytes), out.data(), width, 0, height,
                    TJPF_RGB, TJFLAG_FASTDCT) != 0) {
    // Warnings (e.g. premature end of data) still count as failures: a frame on the wire is whole.
    if (error) *error = std::string("jpeg: ") + tjGetErrorStr2(handle_);
    return std::nullopt;
  }
  return out;
}

}  // namespace rgbdquad::encodings
