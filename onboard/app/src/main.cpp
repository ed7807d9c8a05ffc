// rgbd-streamer: captures a Kinect v1 (libfreenect), any OpenNI2 device, or a TUM RGB-D folder,
// drops blank/malformed frames, registers depth to RGB where needed, and streams RGB and depth to
// the ground station over two TCP connections (protocol/, docs/onboard.md). Runs until stopped
// (SIGINT/SIGTERM) or, for a replay without loop, until the replay ends.
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <functional>
#include <iostream>
#include <memory>
#include <thread>
#include <vector>

#include "rgbdquad/app/streamer_config.h"
#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/freenect_source.h"
#include "rgbdquad/capture/openni2_source.h"
#include "rgbdquad/capture/tum_replay_source.h"
#include "rgbdquad/stream/payload_encoder.h"
#include "rgbdquad/stream/pipeline.h"
#include "rgbdquad/stream/stream_sender.h"

namespace {

using namespace rgbdquad;

constexpr const char* kDefaultConfigPath = "/etc/rgbd-streamer/rgbd-streamer.yaml";

std::unique_ptr<capture::FrameSource> make_source(const app::StreamerConfig& c,
                                                  capture::Clock* clock) {
  if (c.source == "tum") {
    capture::TumReplayOptions o;
    o.directory = c.tum_directory;
    o.fps = c.tum_fps;
    o.loop = c.tum_loop;
    o.preload = c.tum_preload;
    o.max_frames = c.max_frames;
    return std::make_unique<capture::TumReplaySource>(o, clock);
  }
  if (c.source == "openni2") {
    capture::OpenNi2Options o;
    o.uri = c.openni2_uri;
    return std::make_unique<capture::OpenNi2Source>(o, clock);
  }
  capture::FreenectOptions o;
  o.device_index = c.freenect_device_index;
  o.disparity_depth = c.freenect_disparity_depth;
  return std::make_unique<capture::FreenectSource>(o, clock);
}

int run(const app::StreamerConfig& config, const protocol::StreamKey& key,
        std::shared_ptr<spdlog::logger> log, const sigset_t& signals) {
  capture::SteadyClock clock;
  auto source = make_source(config, &clock);
  log->info("source: {}", source->describe());

  stream::StreamSenderOptions rgb_options;
  rgb_options.host = config.host;
  rgb_options.key = key;
  rgb_options.kind = protocol::StreamKind::kRgb;
  rgb_options.port = config.rgb_port;
  rgb_options.encoding = *stream::rgb_encoding_from_string(config.rgb_encoding);
  rgb_options.intrinsics = {
      config.rgb_intrinsics[0],
      config.rgb_intrinsics[1],
      config.rgb_intrinsics[2],
      config.rgb_intrinsics[3],
      {config.rgb_distortion[0], config.rgb_distortion[1], config.rgb_distortion[2],
       config.rgb_distortion[3], config.rgb_distortion[4]}};
  rgb_options.device_id = config.device_id;
  rgb_options.jpeg_quality = config.jpeg_quality;
  rgb_options.zstd_level = config.zstd_level;
  stream::StreamSenderOptions depth_options = rgb_options;
  depth_options.kind = protocol::StreamKind::kDepth;
  depth_options.port = config.depth_port;
  depth_options.encoding = *stream::depth_encoding_from_string(config.depth_encoding);
  if (config.pair_depth_with_rgb) {
    auto hint = std::make_shared<stream::PairHint>();
    rgb_options.pair_hint = hint;
    depth_options.pair_hint = hint;
    depth_options.held_frames = 6;  // 200 ms at 30 fps (see StreamSenderOptions::held_frames)
  }
  depth_options.depth_units_per_m =
      config.source == "tum" ? capture::kTumDepthUnitsPerM : capture::kMillimetreUnitsPerM;

  std::optional<capture::RegistrationOptions> registration;
  if (config.registration_enabled) {
    capture::RegistrationOptions r;
    r.depth = {config.depth_intrinsics[0], config.depth_intrinsics[1], config.depth_intrinsics[2],
               config.depth_intrinsics[3]};
    r.rgb = {config.rgb_intrinsics[0], config.rgb_intrinsics[1], config.rgb_intrinsics[2],
             config.rgb_intrinsics[3]};
    r.R_rgb_depth = config.R_rgb_depth;
    r.t_rgb_depth_m = config.t_rgb_depth_m;
    std::string why;
    if (!r.is_valid(&why)) throw std::runtime_error("registration: " + why);
    registration = r;
  }
  capture::FrameValidatorOptions validation;
  validation.rgb_black_level = config.rgb_black_level;

  stream::StreamSender rgb(rgb_options, &clock, log);
  stream::StreamSender depth(depth_options, &clock, log);
  stream::StreamerPipeline pipeline(source.get(), validation, registration, &rgb, &depth);

  std::atomic<bool> stop{false};
  // Signals are blocked in every thread; this one waits for them (no handler, no global state).
  std::thread signal_thread([&] {
    int signal_number = 0;
    sigwait(&signals, &signal_number);
    if (signal_number != SIGUSR2) log->info("signal {}: stopping", signal_number);
    stop = true;
    source->stop();
  });
  const auto period_us = static_cast<std::int64_t>(config.stats_period_s * 1e6);
  pipeline.run(stop, &clock, period_us, log.get());
  if (!stop) {
    if (!source->error().empty()) log->warn("source ended: {}", source->error());
    // A replay ended: give the receiver a moment to request the last frames.
    const std::int64_t deadline_us = clock.now_us() + std::int64_t{config.exit_linger_ms} * 1000;
    auto pending = [&] {
      const auto c = pipeline.counters();
      return c.rgb.sent + c.rgb.superseded < c.rgb.published ||
             c.depth.sent + c.depth.superseded < c.depth.published;
    };
    while (pending() && clock.now_us() < deadline_us)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const auto final_counters = pipeline.counters();
  log->info("final: {}", stream::format_stats(final_counters, {}, 0));
  pthread_kill(signal_thread.native_handle(), SIGUSR2);  // wake the signal thread if still waiting
  signal_thread.join();
  return stop ? 0 : (source->error().empty() || config.source != "freenect" ? 0 : 3);
}

}  // namespace

int main(int argc, char** argv) {
  app::StreamerConfig defaults;
  app::StreamerConfig cli;
  CLI::App parser{
      "rgbd-streamer: capture a Kinect v1 (libfreenect; also replays a fakenect dump under\n"
      "`fakenect <dump> rgbd-streamer ...`), an OpenNI2 device or a TUM RGB-D folder, drop blank "
      "and\n"
      "malformed frames, register depth to RGB where the driver does not, and stream RGB and depth "
      "to\n"
      "the ground station over two TCP connections (protocol v1), reconnecting forever.\n"
      "Settings: built-in defaults < config file < these options. Logs go to stderr."};
  std::string config_path;
  bool print_config = false;
  std::vector<std::function<void(app::StreamerConfig*)>> overrides;
  auto over = [&](CLI::Option* option, auto apply) {
    overrides.push_back([option, apply](app::StreamerConfig* c) {
      if (option->count() > 0) apply(c);
    });
  };
  parser.add_option(
      "-c,--config", config_path,
      std::string("YAML config file (default ") + kDefaultConfigPath + " if it exists)");
  parser.add_flag("--print-config", print_config, "print the effective configuration and exit");
  over(parser.add_option("--source", cli.source, "freenect | openni2 | tum (default freenect)"),
       [&](auto* c) { c->source = cli.source; });
  over(parser.add_option("--freenect-device", cli.freenect_device_index,
                         "libfreenect device index (default 0)"),
       [&](auto* c) { c->freenect_device_index = cli.freenect_device_index; });
  over(parser.add_flag("--freenect-disparity-depth", cli.freenect_disparity_depth,
                       "use the 11-bit disparity mode, convert to mm and register in software "
                       "(fakenect dumps: Debian's fakenect replays only this mode)"),
       [&](auto* c) { c->freenect_disparity_depth = cli.freenect_disparity_depth; });
  over(parser.add_option("--openni2-uri", cli.openni2_uri,
                         "OpenNI2 device URI (default: first device)"),
       [&](auto* c) { c->openni2_uri = cli.openni2_uri; });
  over(parser.add_option("--tum-dir", cli.tum_directory,
                         "TUM RGB-D folder (rgb.txt, depth.txt) for --source tum"),
       [&](auto* c) { c->tum_directory = cli.tum_directory; });
  over(parser.add_option("--tum-fps", cli.tum_fps,
                         "0 = original timing, > 0 = RGB frames per second, < 0 = unpaced"),
       [&](auto* c) { c->tum_fps = cli.tum_fps; });
  over(parser.add_option("--tum-loop", cli.tum_loop, "replay forever (true/false, default true)"),
       [&](auto* c) { c->tum_loop = cli.tum_loop; });
  over(parser.add_option("--max-frames", cli.max_frames,
                         "stop after this many captured frames (0 = never)"),
       [&](auto* c) { c->max_frames = cli.max_frames; });
  over(parser.add_option("--host", cli.host, "ground-station address (default 192.168.1.10)"),
       [&](auto* c) { c->host = cli.host; });
  over(
      parser.add_option(
          "--stream-key-file", cli.stream_key_file,
          "file holding the craft's stream key (default /etc/rgbd-streamer/stream.key, mode 0600)"),
      [&](auto* c) { c->stream_key_file = cli.stream_key_file; });
  over(parser.add_option("--rgb-port", cli.rgb_port,
                         "ground-station RGB stream port (default 5600)"),
       [&](auto* c) { c->rgb_port = cli.rgb_port; });
  over(parser.add_option("--depth-port", cli.depth_port,
                         "ground-station depth stream port (default 5601)"),
       [&](auto* c) { c->depth_port = cli.depth_port; });
  over(parser.add_option("--depth-encoding", cli.depth_encoding,
                         "raw | rvl | zstd-delta (default rvl, lossless)"),
       [&](auto* c) { c->depth_encoding = cli.depth_encoding; });
  over(parser.add_option("--rgb-encoding", cli.rgb_encoding, "raw | jpeg (default raw)"),
       [&](auto* c) { c->rgb_encoding = cli.rgb_encoding; });
  over(parser.add_option("--jpeg-quality", cli.jpeg_quality, "JPEG quality 1..100 (default 90)"),
       [&](auto* c) { c->jpeg_quality = cli.jpeg_quality; });
  over(parser.add_option(
           "--pair-depth-with-rgb", cli.pair_depth_with_rgb,
           "send the depth frame nearest the RGB frame just sent (true/false, default true)"),
       [&](auto* c) { c->pair_depth_with_rgb = cli.pair_depth_with_rgb; });
  over(parser.add_option("--stats-period", cli.stats_period_s,
                         "seconds between counter lines, 0 = off (default 5)"),
       [&](auto* c) { c->stats_period_s = cli.stats_period_s; });
  over(parser.add_option("--log-level", cli.log_level,
                         "trace | debug | info | warn | error (default info)"),
       [&](auto* c) { c->log_level = cli.log_level; });
  over(parser.add_option(
           "--exit-linger-ms", cli.exit_linger_ms,
           "after a replay ends, wait this long for the last frames to go (default 2000)"),
       [&](auto* c) { c->exit_linger_ms = cli.exit_linger_ms; });
  CLI11_PARSE(parser, argc, argv);

  auto log = spdlog::stderr_color_mt("rgbd-streamer");
  log->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");
  app::StreamerConfig config = defaults;
  try {
    if (!config_path.empty()) {
      app::load_yaml_file(config_path, &config);
    } else if (FILE* f = std::fopen(kDefaultConfigPath, "r")) {
      std::fclose(f);
      config_path = kDefaultConfigPath;
      app::load_yaml_file(config_path, &config);
    }
    for (auto& apply : overrides) apply(&config);
    std::string why;
    if (!config.is_valid(&why)) throw std::runtime_error("invalid configuration: " + why);
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    return 2;
  }
  if (print_config) {
    std::cout << config.to_string();
    return 0;
  }
  std::string key_error;
  const auto key = protocol::load_stream_key_file(config.stream_key_file, &key_error);
  if (!key) {
    log->error("{}", key_error);
    return 2;
  }
  log->set_level(spdlog::level::from_str(config.log_level));
  log->info("configuration ({}):\n{}", config_path.empty() ? "defaults + options" : config_path,
            config.to_string());

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGUSR2);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  try {
    return run(config, *key, log, signals);
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    return 1;
  }
}
