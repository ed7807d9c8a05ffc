// Lossless depth codecs for the wire: RVL (A. D. Wilson, "Fast Lossless Depth Image Compression",
// ISS 2017) and general-purpose compressors (zstd, LZ4) applied to horizontally delta-coded depth.
// These payload formats are part of the wire contract (protocol/encodings/README.md): the streamer
// encodes with them, the ground-station receiver decodes with them.
//
// All functions are pure and thread-safe (no shared state). Decoders never trust their input:
// malformed, truncated or oversized payloads yield std::nullopt and an error message, never a
// crash.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rgbdquad::encodings {

// How a depth image (uint16 per pixel, row-major, millimetres, 0 = no reading) is carried.
enum class DepthCodec : std::uint8_t {
  kRaw = 0,        // little-endian uint16 per pixel, 2 bytes/pixel
  kRvl = 1,        // RVL: zero-run lengths + zig-zag deltas in 3-bit variable-length nibbles
  kZstdDelta = 2,  // zstd frame of little-endian uint16 row-wise deltas (mod 2^16)
  kLz4Delta = 3,   // 4-byte LE raw size + LZ4 block of the same deltas
};

// Human-readable name ("raw", "rvl", "zstd-delta", "lz4-delta") and the reverse lookup.
const char* to_string(DepthCodec codec);
std::optional<DepthCodec> depth_codec_from_string(const std::string& name);

// Encodes width*height pixels. `zstd_level` only applies to kZstdDelta (1 is fast; see README).
std::vector<std::uint8_t> encode_depth(DepthCodec codec, const std::uint16_t* depth_mm, int width,
                                       int height, int zstd_level = 1);

// Decodes a payload that must hold exactly width*height pixels.
std::optional<std::vector<std::uint16_t>> decode_depth(DepthCodec codec,
                                                       const std::uint8_t* payload,
                                                       std::size_t payload_bytes, int width,
                                                       int height, std::string* error);

// The individual algorithms, exposed for tests and benchmarks.
std::vector<std::uint8_t> rvl_encode(const std::uint16_t* depth, std::size_t pixel_count);
std::optional<std::vector<std::uint16_t>> rvl_decode(const std::uint8_t* payload,
                                                     std::size_t payload_bytes,
                                                     std::size_t pixel_count, std::string* error);

}  // namespace rgbdquad::encodings
