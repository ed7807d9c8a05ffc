// Lossless depth codecs: RVL and delta + zstd/LZ4. See depth_codec.h and README.md for the formats.
#include "rgbdquad/encodings/depth_codec.h"

#include <lz4.h>
#include <zstd.h>

#include <limits>

namespace rgbdquad::encodings {
namespace {

// Upper bound on decoded image size: 4096x4096 pixels. Far above the Kinect's 640x480; it only
// stops a corrupted header from making a decoder allocate gigabytes.
constexpr std::size_t kMaxPixelCount = 4096u * 4096u;

bool dims_ok(int width, int height, std::string* error) {
  if (width <= 0 || height <= 0 ||
      static_cast<std::size_t>(width) * static_cast<std::size_t>(height) > kMaxPixelCount) {
    if (error)
      *error = "invalid image size " + std::to_string(width) + "x" + std::to_string(height);
    return false;
  }
  return true;
}

// --- RVL -----------------------------------------------------------------------------------
// Nibbles are packed 8 per 32-bit word, first nibble in the most significant bits; words are
// written little-endian. A value is written as 3-bit groups, least significant first, the 4th
// bit of a nibble set when more groups follow.
class NibbleWriter {
 public:
  explicit NibbleWriter(std::vector<std::uint8_t>* out) : out_(out) {}
  void put_value(std::uint32_t value) {
    do {
      std::uint32_t nibble = value & 0x7u;
      value >>= 3;
      if (value != 0) nibble |= 0x8u;
      word_ = (word_ << 4) | nibble;
      if (++nibbles_ == 8) flush_word();
    } while (value != 0);
  }
  void finish() {
    if (nibbles_ == 0) return;
    word_ <<= 4 * (8 - nibbles_);
    flush_word();
  }

 private:
  void flush_word() {
    for (int i = 0; i < 4; ++i) out_->push_back(static_cast<std::uint8_t>(word_ >> (8 * i)));
    word_ = 0;
    nibbles_ = 0;
  }
  std::vector<std::uint8_t>* out_;
  std::uint32_t word_ = 0;
  int nibbles_ = 0;
};

class NibbleReader {
 public:
  NibbleReader(const std::uint8_t* data, std::size_t bytes) : data_(data), bytes_(bytes) {}
  // Reads one variable-length value; false on truncation or a value wider than 32 bits.
  bool get_value(std::uint32_t* value) {
    std::uint32_t result = 0;
    int shift = 0;
    while (true) {
      if (nibbles_left_ == 0) {
        if (offset_ + 4 > bytes_) return false;
        word_ = static_cast<std::uint32_t>(data_[offset_]) |
                (static_cast<std::uint32_t>(data_[offset_ + 1]) << 8) |
                (static_cast<std::uint32_t>(data_[offset_ + 2]) << 16) |
                (static_cast<std::uint32_t>(data_[offset_ + 3]) << 24);
        offset_ += 4;
        nibbles_left_ = 8;
      }
      const std::uint32_t nibble = word_ >> 28;
      word_ <<= 4;
      --nibbles_left_;
      if (shift > 30) return false;
      result |= (nibble & 0x7u) << shift;
      shift += 3;
      if ((nibble & 0x8u) == 0) break;
    }
    *value = result;
    return true;
  }
  std::size_t bytes_consumed() const { return offset_; }

 private:
  const std::uint8_t* data_;
  std::size_t bytes_;
  std::size_t offset_ = 0;
  std::uint32_t word_ = 0;
  int nibbles_left_ = 0;
};

// Zig-zag maps signed deltas to unsigned so that small magnitudes get short codes.
std::uint32_t zigzag(std::int32_t delta) {
  return (static_cast<std::uint32_t>(delta) << 1) ^ static_cast<std::uint32_t>(delta >> 31);
}
std::int32_t unzigzag(std::uint32_t value) {
  return static_cast<std::int32_t>(value >> 1) ^ -static_cast<std::int32_t>(value & 1u);
}

// --- delta coding for the general-purpose compressors ---------------------------------------
// Each row's first pixel is coded against 0, the rest against their left neighbour, mod 2^16,
// written little-endian: smooth depth becomes runs of small values that zstd/LZ4 compress well.
std::vector<std::uint8_t> delta_bytes(const std::uint16_t* depth, int width, int height) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(width) * height * 2);
  std::size_t o = 0;
  for (int y = 0; y < height; ++y) {
    std::uint16_t previous = 0;
    const std::uint16_t* row = depth + static_cast<std::size_t>(y) * width;
    for (int x = 0; x < width; ++x) {
      const auto delta = static_cast<std::uint16_t>(row[x] - previous);
      previous = row[x];
      out[o++] = static_cast<std::uint8_t>(delta & 0xFF);
      out[o++] = static_cast<std::uint8_t>(delta >> 8);
    }
  }
  return out;
}

std::vector<std::uint16_t> undelta(const std::uint8_t* bytes, int width, int height) {
  std::vector<std::uint16_t> out(static_cast<std::size_t>(width) * height);
  std::size_t i = 0;
  for (int y = 0; y < height; ++y) {
    std::uint16_t previous = 0;
    for (int x = 0; x < width; ++x, ++i) {
      const auto delta = static_cast<std::uint16_t>(bytes[2 * i] | (bytes[2 * i + 1] << 8));
      previous = static_cast<std::uint16_t>(previous + delta);
      out[i] = previous;
    }
  }
  return out;
}

constexpr std::size_t kLz4SizePrefixBytes = 4;

}  // namespace

const char* to_string(DepthCodec codec) {
  switch (codec) {
    case DepthCodec::kRaw:
      return "raw";
    case DepthCodec::kRvl:
      return "rvl";
    case DepthCodec::kZstdDelta:
      return "zstd-delta";
    case DepthCodec::kLz4Delta:
      return "lz4-delta";
  }
  return "unknown";
}

std::optional<DepthCodec> depth_codec_from_string(const std::string& name) {
  for (DepthCodec c :
       {DepthCodec::kRaw, DepthCodec::kRvl, DepthCodec::kZstdDelta, DepthCodec::kLz4Delta}) {
    if (name == to_string(c)) return c;
  }
  return std::nullopt;
}

std::vector<std::uint8_t> rvl_encode(const std::uint16_t* depth, std::size_t pixel_count) {
  std::vector<std::uint8_t> out;
  out.reserve(pixel_count);  // typical Kinect depth compresses to well under 1 byte/pixel
  NibbleWriter writer(&out);
  const std::uint16_t* p = depth;
  const std::uint16_t* end = depth + pixel_count;
  std::int32_t previous = 0;
  while (p != end) {
    std::uint32_t zeros = 0;
    while (p != end && *p == 0) {
      ++p;
      ++zeros;
    }
    writer.put_value(zeros);
    std::uint32_t nonzeros = 0;
    for (const std::uint16_t* q = p; q != end && *q != 0; ++q) ++nonzeros;
    writer.put_value(nonzeros);
    for (std::uint32_t i = 0; i < nonzeros; ++i, ++p) {
      const std::int32_t current = *p;
      writer.put_value(zigzag(current - previous));
      previous = current;
    }
  }
  writer.finish();
  return out;
}

std::optional<std::vector<std::uint16_t>> rvl_decode(const std::uint8_t* payload,
                                                     std::size_t payload_bytes,
                                                     std::size_t pixel_count, std::string* error) {
  auto fail = [&](const char* why) -> std::optional<std::vector<std::uint16_t>> {
    if (error) *error = std::string("rvl: ") + why;
    return std::nullopt;
  };
  if (pixel_count > kMaxPixelCount) return fail("pixel count too large");
  std::vector<std::uint16_t> out(pixel_count, 0);
  NibbleReader reader(payload, payload_bytes);
  std::size_t i = 0;
  std::int32_t previous = 0;
  while (i < pixel_count) {
    std::uint32_t zeros = 0;
    std::uint32_t nonzeros = 0;
    if (!reader.get_value(&zeros)) return fail("truncated zero run");
    if (zeros > pixel_count - i) return fail("zero run past end of image");
    i += zeros;
    if (!reader.get_value(&nonzeros)) return fail("truncated value run");
    if (nonzeros > pixel_count - i) return fail("value run past end of image");
    for (std::uint32_t k = 0; k < nonzeros; ++k) {
      std::uint32_t coded = 0;
      if (!reader.get_value(&coded)) return fail("truncated delta");
      const std::int64_t current = static_cast<std::int64_t>(previous) + unzigzag(coded);
      if (current <= 0 || current > std::numeric_limits<std::uint16_t>::max()) {
        return fail("delta leaves the uint16 range");
      }
      out[i++] = static_cast<std::uint16_t>(current);
      previous = static_cast<std::int32_t>(current);
    }
  }
  // Padding: the last word may hold unused nibbles, but whole words past it mean a bad payload.
  if (reader.bytes_consumed() != payload_bytes) return fail("trailing bytes after image");
  return out;
}

std::vector<std::uint8_t> encode_depth(DepthCodec codec, const std::uint16_t* depth_mm, int width,
                                       int height, int zstd_level) {
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  switch (codec) {
    case DepthCodec::kRaw: {
      std::vector<std::uint8_t> out(n * 2);
      for (std::size_t i = 0; i < n; ++i) {
        out[2 * i] = static_cast<std::uint8_t>(depth_mm[i] & 0xFF);
        out[2 * i + 1] = static_cast<std::uint8_t>(depth_mm[i] >> 8);
      }
      return out;
    }
    case DepthCodec::kRvl:
      return rvl_encode(depth_mm, n);
    case DepthCodec::kZstdDelta: {
      const std::vector<std::uint8_t> deltas = delta_bytes(depth_mm, width, height);
      std::vector<std::uint8_t> out(ZSTD_compressBound(deltas.size()));
      const std::size_t written =
          ZSTD_compress(out.data(), out.size(), deltas.data(), deltas.size(), zstd_level);
      // Cannot fail with a compressBound-sized buffer and a valid level (levels are clamped).
      out.resize(ZSTD_isError(written) ? 0 : written);
      return out;
    }
    case DepthCodec::kLz4Delta: {
      const std::vector<std::uint8_t> deltas = delta_bytes(depth_mm, width, height);
      const int bound = LZ4_compressBound(static_cast<int>(deltas.size()));
      std::vector<std::uint8_t> out(kLz4SizePrefixBytes + static_cast<std::size_t>(bound));
      const auto raw_size = static_cast<std::uint32_t>(deltas.size());
      for (std::size_t b = 0; b < kLz4SizePrefixBytes; ++b) {
        out[b] = static_cast<std::uint8_t>(raw_size >> (8 * b));
      }
      const int written =
          LZ4_compress_default(reinterpret_cast<const char*>(deltas.data()),
                               reinterpret_cast<char*>(out.data() + kLz4SizePrefixBytes),
                               static_cast<int>(deltas.size()), bound);
      out.resize(kLz4SizePrefixBytes + static_cast<std::size_t>(written > 0 ? written : 0));
      return out;
    }
  }
  return {};
}

std::optional<std::vector<std::uint16_t>> decode_depth(DepthCodec codec,
                                                       const std::uint8_t* payload,
                                                       std::size_t payload_bytes, int width,
                                                       int height, std::string* error) {
  if (!dims_ok(width, height, error)) return std::nullopt;
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  auto fail = [&](const std::string& why) -> std::optional<std::vector<std::uint16_t>> {
    if (error) *error = std::string(to_string(codec)) + ": " + why;
    return std::nullopt;
  };
  switch (codec) {
    case DepthCodec::kRaw: {
      if (payload_bytes != n * 2)
        return fail("payload is " + std::to_string(payload_bytes) + " bytes, expected " +
                    std::to_string(n * 2));
      std::vector<std::uint16_t> out(n);
      for (std::size_t i = 0; i < n; ++i) {
        out[i] = static_cast<std::uint16_t>(payload[2 * i] | (payload[2 * i + 1] << 8));
      }
      return out;
    }
    case DepthCodec::kRvl:
      return rvl_decode(payload, payload_bytes, n, error);
    case DepthCodec::kZstdDelta: {
      const unsigned long long content = ZSTD_getFrameContentSize(payload, payload_bytes);
      if (content == ZSTD_CONTENTSIZE_ERROR || content == ZSTD_CONTENTSIZE_UNKNOWN) {
        return fail("not a zstd frame with a known size");
      }
      if (content != n * 2) return fail("decoded size does not match the image size");
      std::vector<std::uint8_t> deltas(n * 2);
      const std::size_t got = ZSTD_decompress(deltas.data(), deltas.size(), payload, payload_bytes);
      if (ZSTD_isError(got)) return fail(ZSTD_getErrorName(got));
      if (got != deltas.size()) return fail("short zstd frame");
      return undelta(deltas.data(), width, height);
    }
    case DepthCodec::kLz4Delta: {
      if (payload_bytes < kLz4SizePrefixBytes) return fail("payload shorter than its size prefix");
      std::uint32_t raw_size = 0;
      for (std::size_t b = 0; b < kLz4SizePrefixBytes; ++b) {
        raw_size |= static_cast<std::uint32_t>(payload[b]) << (8 * b);
      }
      if (raw_size != n * 2) return fail("decoded size does not match the image size");
      std::vector<std::uint8_t> deltas(n * 2);
      const int got = LZ4_decompress_safe(
          reinterpret_cast<const char*>(payload + kLz4SizePrefixBytes),
          reinterpret_cast<char*>(deltas.data()),
          static_cast<int>(payload_bytes - kLz4SizePrefixBytes), static_cast<int>(deltas.size()));
      if (got != static_cast<int>(deltas.size())) return fail("corrupt LZ4 block");
      return undelta(deltas.data(), width, height);
    }
  }
  return fail("unknown codec");
}

}  // namespace rgbdquad::encodings
