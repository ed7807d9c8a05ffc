// rgbd-receiver: a ground-station receiver on its own, for trying the link by hand and for
// demos: accepts rgbd-streamer's two connections, prints per-stream counters and the newest
// RGB-D pair once per period, until SIGINT/SIGTERM or --seconds.
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>

#include "rgbdquad/receiver/stream_receiver.h"

int main(int argc, char** argv) {
  using namespace rgbdquad;
  receiver::ReceiverOptions options;
  double period_s = 1.0;
  double seconds = 0;
  CLI::App app{
      "rgbd-receiver: accept rgbd-streamer's RGB and depth streams and print what arrives"};
  app.add_option(
      "--bind", options.bind_address,
      "listen address (default 127.0.0.1; the ground station's WiFi address for the craft)");
  app.add_option("--rgb-port", options.rgb_port, "RGB stream port (default 5600)");
  app.add_option("--depth-port", options.depth_port, "depth stream port (default 5601)");
  std::string key_file;
  app.add_option("--key-file", key_file,
                 "file holding the craft's stream key (32 hex digits, mode 0600; the streamer's "
                 "stream_key_file)")
      ->required();
  app.add_option("--credits", options.credits_in_flight,
                 "frames in flight per stream, 1..8 (default 2)");
  app.add_option("--period", period_s, "seconds between status lines (default 1)");
  app.add_option("--seconds", seconds,
                 "stop after this many seconds (default 0 = until SIGINT/SIGTERM)");
  CLI11_PARSE(app, argc, argv);
  auto log = spdlog::stderr_color_mt("rgbd-receiver");
  std::string why;
  if (auto key = protocol::load_stream_key_file(key_file, &why)) {
    options.key = *key;
  } else {
    log->error("{}", why);
    return 2;
  }
  if (!options.is_valid(&why) || !(period_s > 0) || seconds < 0) {
    log->error("invalid options: {}", why.empty() ? "period must be > 0, seconds >= 0" : why);
    return 2;
  }
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  const auto now_us = [] {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  try {
    receiver::StreamReceiver rx(options, now_us, log);
    log->info("listening on {}: rgb {} depth {}", options.bind_address, rx.rgb_port(),
              rx.depth_port());
    const std::int64_t start_us = now_us();
    receiver::ReceiverCounters previous;
    const timespec period{static_cast<time_t>(period_s),
                          static_cast<long>((period_s - static_cast<time_t>(period_s)) * 1e9)};
    while (seconds == 0 || now_us() - start_us < static_cast<std::int64_t>(seconds * 1e6)) {
      if (sigtimedwait(&signals, nullptr, &period) > 0) break;
      const auto c = rx.counters();
      const auto pair = rx.newest_pair();
      std::printf(
          "rgb %llu (+%llu) depth %llu (+%llu) pairs %llu | crc errors %llu | invalid %llu | "
          "%.1f MB received | newest pair gap %s\n",
          static_cast<unsigned long long>(c.rgb.frames),
          static_cast<unsigned long long>(c.rgb.frames - previous.rgb.frames),
          static_cast<unsigned long long>(c.depth.frames),
          static_cast<unsigned long long>(c.depth.frames - previous.depth.frames),
          static_cast<unsigned long long>(c.pairs),
          static_cast<unsigned long long>(c.rgb.crc_errors + c.depth.crc_errors),
          static_cast<unsigned long long>(c.rgb.invalid_frames + c.depth.invalid_frames),
          static_cast<double>(c.rgb.wire_bytes + c.depth.wire_bytes) / 1e6,
          pair ? (std::to_string(pair->gap_us() / 1000.0) + " ms").c_str() : "-");
      std::fflush(stdout);
      previous = c;
    }
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    return 1;
  }
  return 0;
}
