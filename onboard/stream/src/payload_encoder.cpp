// Frame -> wire payload in the negotiated encoding.
#include "rgbdquad/stream/payload_encoder.h"

#include <stdexcept>

#include "rgbdquad/encodings/depth_codec.h"
#include "rgbdquad/encodings/jpeg_codec.h"

namespace rgbdquad::stream {

using protocol::Encoding;

std::optional<Encoding> depth_encoding_from_string(const std::string& name) {
  if (name == "raw") return Encoding::kRaw;
  if (name == "rvl") return Encoding::kDepthRvl;
  if (name == "zstd-delta") return Encoding::kDepthZstdDelta;
  return std::nullopt;
}

std::optional<Encoding> rgb_encoding_from_string(const std::string& name) {
  if (name == "raw") return Encoding::kRaw;
  if (name == "jpeg") return Encoding::kRgbJpeg;
  return std::nullopt;
}

std::string encoding_name(Encoding encoding) {
  switch (encoding) {
    case Encoding::kRaw:
      return "raw";
    case Encoding::kDepthRvl:
      return "rvl";
    case Encoding::kDepthZstdDelta:
      return "zstd-delta";
    case Encoding::kRgbJpeg:
      return "jpeg";
  }
  return "unknown";
}

PayloadEncoder::PayloadEncoder(protocol::StreamKind kind, Encoding encoding, int jpeg_quality,
                               int zstd_level)
    : kind_(kind), encoding_(encoding), zstd_level_(zstd_level) {
  const auto format = kind == protocol::StreamKind::kRgb ? protocol::PixelFormat::kRgb8
                                                         : protocol::PixelFormat::kDepth16;
  if (!protocol::encoding_allows_pixel_format(encoding, format)) {
    throw std::invalid_argument("encoding " + encoding_name(encoding) + " cannot carry " +
                                std::string(protocol::to_string(format)));
  }
  if (encoding == Encoding::kRgbJpeg)
    jpeg_ = std::make_unique<encodings::JpegEncoder>(jpeg_quality);
}

PayloadEncoder::~PayloadEncoder() = default;

std::optional<std::vector<std::uint8_t>> PayloadEncoder::encode(const capture::SourceFrame& frame,
                                                                std::string* error) {
  if (kind_ == protocol::StreamKind::kRgb) {
    const auto* rgb = std::get_if<capture::RgbFrame>(&frame);
    if (rgb == nullptr) {
      *error = "depth frame given to the RGB stream";
      return std::nullopt;
    }
    if (encoding_ == Encoding::kRgbJpeg)
      return jpeg_->encode(rgb->rgb.data(), rgb->width, rgb->height, error);
    return rgb->rgb;
  }
  const auto* depth = std::get_if<capture::DepthFrame>(&frame);
  if (depth == nullptr) {
    *error = "RGB frame given to the depth stream";
    return std::nullopt;
  }
  const encodings::DepthCodec codec = encoding_ == Encoding::kDepthRvl ? encodings::DepthCodec::kRvl
                                      : encoding_ == Encoding::kDepthZstdDelta
                                          ? encodings::DepthCodec::kZstdDelta
                                          : encodings::DepthCodec::kRaw;
  return encodings::encode_depth(codec, depth->depth.data(), depth->width, depth->height,
                                 zstd_level_);
}

}  // namespace rgbdquad::stream
