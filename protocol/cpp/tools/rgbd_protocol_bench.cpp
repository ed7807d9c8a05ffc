// rgbd-protocol-bench: codec cost per Kinect-sized frame (encode, and decode through the
// StreamDecoder fed in 64 KiB reads like a socket), printed as a table. Not a test: figures only.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "rgbdquad/protocol/codec.hpp"

namespace {

namespace proto = rgbdquad::protocol;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kReadBytes = 65536;  // a typical socket read

double us_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}

void bench(const char* label, proto::PixelFormat format, int frames) {
  const std::size_t bpp = format == proto::PixelFormat::kRgb8 ? 3 : 2;
  proto::Frame frame;
  frame.image.header = {0,
                        0,
                        0,
                        640,
                        480,
                        format,
                        proto::Encoding::kRaw,
                        static_cast<std::uint32_t>(640 * 480 * bpp)};
  frame.image.payload.resize(640 * 480 * bpp);
  for (std::size_t i = 0; i < frame.image.payload.size(); ++i)
    frame.image.payload[i] = static_cast<std::uint8_t>(i * 31);

  std::vector<std::uint8_t> bytes;
  auto t0 = Clock::now();
  for (int i = 0; i < frames; ++i) {
    frame.image.header.sequence = static_cast<std::uint32_t>(i);
    bytes = proto::encode_frame(frame.image.header, frame.image.payload.data(),
                                frame.image.payload.size())
                .bytes;
  }
  const double encode_us = us_since(t0) / frames;

  proto::StreamDecoder decoder;
  int decoded = 0;
  t0 = Clock::now();
  for (int i = 0; i < frames; ++i) {
    for (std::size_t off = 0; off < bytes.size(); off += kReadBytes) {
      decoder.feed(bytes.data() + off, std::min(kReadBytes, bytes.size() - off));
      for (auto r = decoder.next(); r.status != proto::DecodeStatus::kNeedMoreBytes;
           r = decoder.next()) {
        if (r.status == proto::DecodeStatus::kMessage) ++decoded;
      }
    }
  }
  const double decode_us = us_since(t0) / frames;
  const double mb = static_cast<double>(bytes.size()) / 1e6;
  std::printf("| %-14s | %9zu | %10.0f | %8.0f | %10.0f | %8.0f | %d/%d |\n", label, bytes.size(),
              encode_us, mb / (encode_us * 1e-6), decode_us, mb / (decode_us * 1e-6), decoded,
              frames);
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 200;
  if (argc == 2 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    std::printf(
        "usage: rgbd-protocol-bench [FRAMES]\n  encodes and decodes FRAMES (default 200) "
        "640x480 RAW RGB8 and DEPTH16 frames, prints us/frame and MB/s\n");
    return 0;
  }
  if (argc == 2) {
    frames = std::atoi(argv[1]);
    if (frames <= 0) {
      std::fprintf(stderr, "FRAMES must be a positive integer\n");
      return 2;
    }
  } else if (argc > 2) {
    std::fprintf(stderr, "usage: rgbd-protocol-bench [FRAMES]\n");
    return 2;
  }
  std::printf(
      "| frame          | wire B    | encode us  | enc MB/s | decode us  | dec MB/s | ok |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  bench("640x480 RGB8", proto::PixelFormat::kRgb8, frames);
  bench("640x480 DEPTH16", proto::PixelFormat::kDepth16, frames);
  return 0;
}
