// rgbd-codec-cost: encodes real TUM frames with one stream encoding exactly as the streamer does
// (stream::PayloadEncoder), for per-frame cost measurements on other architectures
// (onboard/bench-arm.sh runs it under qemu-user with an instruction-counting plugin: instructions
// per frame = (count with --frames K - count with --frames 0) / K, so loading the PNGs cancels
// out). Prints the wall time per frame of this process and the mean payload size; asserts nothing.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>

#include "rgbdquad/capture/tum_replay_source.h"
#include "rgbdquad/stream/payload_encoder.h"

int main(int argc, char** argv) {
  using namespace rgbdquad;
  CLI::App app{"rgbd-codec-cost: encode TUM frames with one streamer encoding, per-frame cost"};
  std::string data, kind_name = "depth", encoding_name = "rvl";
  std::size_t frames = 30, load = 10;
  int jpeg_quality = 90,
      zstd_level = 1;  // the streamer's defaults (onboard/config/rgbd-streamer.yaml)
  app.add_option("--data", data, "TUM RGB-D folder")->required();
  app.add_option("--stream", kind_name, "depth | rgb")->check(CLI::IsMember({"depth", "rgb"}));
  app.add_option("--encoding", encoding_name, "depth: raw | rvl | zstd-delta; rgb: raw | jpeg");
  app.add_option("--jpeg-quality", jpeg_quality, "JPEG quality (default 90, the streamer's)");
  app.add_option("--zstd-level", zstd_level, "zstd level (default 1, the streamer's)");
  app.add_option("--frames", frames,
                 "frames to encode, cycling over the loaded ones (0 = load only)");
  app.add_option("--load", load, "frames of the stream to load from the folder (default 10)");
  CLI11_PARSE(app, argc, argv);
  const bool depth = kind_name == "depth";
  const auto encoding = depth ? stream::depth_encoding_from_string(encoding_name)
                              : stream::rgb_encoding_from_string(encoding_name);
  if (!encoding || load == 0) {
    std::fprintf(stderr, "rgbd-codec-cost: unknown %s encoding '%s' or --load 0\n",
                 kind_name.c_str(), encoding_name.c_str());
    return 2;
  }
  try {
    capture::ManualClock clock;
    capture::TumReplayOptions o;
    o.directory = data;
    o.fps = -1;
    capture::TumReplaySource source(o, &clock);
    std::vector<capture::SourceFrame> loaded;
    while (loaded.size() < load) {
      auto frame = source.next();
      if (!frame) break;
      if (std::holds_alternative<capture::DepthFrame>(*frame) == depth)
        loaded.push_back(std::move(*frame));
    }
    if (loaded.empty()) throw std::runtime_error("no " + kind_name + " frames in " + data);
    stream::PayloadEncoder encoder(
        depth ? protocol::StreamKind::kDepth : protocol::StreamKind::kRgb, *encoding, jpeg_quality,
        zstd_level);
    double bytes = 0;
    const auto start = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < frames; ++i) {
      std::string error;
      const auto payload = encoder.encode(loaded[i % loaded.size()], &error);
      if (!payload) throw std::runtime_error(error);
      bytes += static_cast<double>(payload->size());
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const double n = frames > 0 ? static_cast<double>(frames) : 1.0;
    std::printf("%s %s: %zu frames, %.3f ms/frame wall, %.0f bytes/frame\n", kind_name.c_str(),
                encoding_name.c_str(), frames, ms / n, bytes / n);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbd-codec-cost: %s\n", e.what());
    return 1;
  }
  return 0;
}
