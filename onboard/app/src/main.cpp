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
#include <cstdio>
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

constexpr int kExitUsage = 2;    // configuration or stream key refused
constexpr int kExitRuntime = 1;  // an exception while streaming

constexpr const char* kDescription =
    "rgbd-streamer: capture a Kinect v1 (libfreenect; also replays a fakenect dump under\n"
    "`fakenect <dump> rgbd-streamer ...`), an OpenNI2 device or a TUM RGB-D folder, drop blank "
    "and\n"
    "malformed frames, register depth to RGB where the driver does not, and stream RGB and depth "
    "to\n"
    "the ground station over two TCP connections (protocol v1), reconnecting forever.\n"
    "Settings: built-in defaults < config file < these options. Logs go to stderr.";

/// The settings the command line overrides: each option writes into its own copy of the field,
/// and apply() copies over the configuration the options that were given. Holds the options'
/// addresses, so it stays where it was built.
class SettingOverrides {
 public:
  SettingOverrides() = default;
  SettingOverrides(const SettingOverrides&) = delete;
  SettingOverrides& operator=(const SettingOverrides&) = delete;

  /// An option taking a value for `field`.
  template <typename T>
  void add(CLI::App& parser, const std::string& name, T app::StreamerConfig::*field,
           const std::string& help) {
    track(parser.add_option(name, given_.*field, help), field);
  }
  /// A flag setting the bool `field`.
  void add_flag(CLI::App& parser, const std::string& name, bool app::StreamerConfig::*field,
                const std::string& help) {
    track(parser.add_flag(name, given_.*field, help), field);
  }
  void apply(app::StreamerConfig* config) const {
    for (const auto& apply_one : appliers_) apply_one(config);
  }

 private:
  template <typename T>
  void track(CLI::Option* option, T app::StreamerConfig::*field) {
    appliers_.push_back([this, option, field](app::StreamerConfig* c) {
      if (option->count() > 0) c->*field = given_.*field;
    });
  }

  app::StreamerConfig given_;
  std::vector<std::function<void(app::StreamerConfig*)>> appliers_;
};

/// The command line.
struct CommandLine {
  std::string config_path;
  bool print_config = false;
  SettingOverrides overrides;
};

void add_options(CLI::App& parser, CommandLine& a) {
  using C = app::StreamerConfig;
  SettingOverrides& o = a.overrides;
  parser.add_option(
      "-c,--config", a.config_path,
      std::string("YAML config file (default ") + kDefaultConfigPath + " if it exists)");
  parser.add_flag("--print-config", a.print_config, "print the effective configuration and exit");
  o.add(parser, "--source", &C::source, "freenect | openni2 | tum (default freenect)");
  o.add(parser, "--freenect-device", &C::freenect_device_index,
        "libfreenect device index (default 0)");
  o.add_flag(parser, "--freenect-disparity-depth", &C::freenect_disparity_depth,
             "use the 11-bit disparity mode, convert to mm and register in software "
             "(fakenect dumps: Debian's fakenect replays only this mode)");
  o.add(parser, "--openni2-uri", &C::openni2_uri, "OpenNI2 device URI (default: first device)");
  o.add(parser, "--tum-dir", &C::tum_directory,
        "TUM RGB-D folder (rgb.txt, depth.txt) for --source tum");
  o.add(parser, "--tum-fps", &C::tum_fps,
        "0 = original timing, > 0 = RGB frames per second, < 0 = unpaced");
  o.add(parser, "--tum-loop", &C::tum_loop, "replay forever (true/false, default true)");
  o.add(parser, "--max-frames", &C::max_frames, "stop after this many captured frames (0 = never)");
  o.add(parser, "--host", &C::host, "ground-station address (default 192.168.1.10)");
  o.add(parser, "--stream-key-file", &C::stream_key_file,
        "file holding the craft's stream key (default /etc/rgbd-streamer/stream.key, mode 0600)");
  o.add(parser, "--rgb-port", &C::rgb_port, "ground-station RGB stream port (default 5600)");
  o.add(parser, "--depth-port", &C::depth_port, "ground-station depth stream port (default 5601)");
  o.add(parser, "--depth-encoding", &C::depth_encoding,
        "raw | rvl | zstd-delta (default rvl, lossless)");
  o.add(parser, "--rgb-encoding", &C::rgb_encoding, "raw | jpeg (default raw)");
  o.add(parser, "--jpeg-quality", &C::jpeg_quality, "JPEG quality 1..100 (default 90)");
  o.add(parser, "--pair-depth-with-rgb", &C::pair_depth_with_rgb,
        "send the depth frame nearest the RGB frame just sent (true/false, default true)");
  o.add(parser, "--stats-period", &C::stats_period_s,
        "seconds between counter lines, 0 = off (default 5)");
  o.add(parser, "--log-level", &C::log_level, "trace | debug | info | warn | error (default info)");
  o.add(parser, "--exit-linger-ms", &C::exit_linger_ms,
        "after a replay ends, wait this long for the last frames to go (default 2000)");
}

/// Built-in defaults < the config file (the one given, else the default path if it exists) < the
/// options given, validated. `file_read` is the config file read (empty: none). Throws (the
/// message is the line to log) on an unreadable file or an invalid configuration.
app::StreamerConfig effective_config(const CommandLine& a, std::string* file_read) {
  app::StreamerConfig config;
  *file_read = a.config_path;
  if (file_read->empty()) {
    if (FILE* f = std::fopen(kDefaultConfigPath, "r")) {
      std::fclose(f);
      *file_read = kDefaultConfigPath;
    }
  }
  if (!file_read->empty()) app::load_yaml_file(*file_read, &config);
  a.overrides.apply(&config);
  std::string why;
  if (!config.is_valid(&why)) throw std::runtime_error("invalid configuration: " + why);
  return config;
}

std::shared_ptr<spdlog::logger> make_logger() {
  auto log = spdlog::stderr_color_mt("rgbd-streamer");
  log->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");
  return log;
}

/// Blocks the stop signals (and SIGUSR2, which wakes run()'s signal thread) in this thread, and
/// so in every thread started after; returns them for sigwait.
sigset_t block_stop_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGUSR2);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return signals;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App parser{kDescription};
  CommandLine args;
  add_options(parser, args);
  CLI11_PARSE(parser, argc, argv);

  auto log = make_logger();
  app::StreamerConfig config;
  std::string config_file;
  try {
    config = effective_config(args, &config_file);
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    return kExitUsage;
  }
  if (args.print_config) {
    std::cout << config.to_string();
    return 0;
  }
  std::string key_error;
  const auto key = protocol::load_stream_key_file(config.stream_key_file, &key_error);
  if (!key) {
    log->error("{}", key_error);
    return kExitUsage;
  }
  log->set_level(spdlog::level::from_str(config.log_level));
  log->info("configuration ({}):\n{}", config_file.empty() ? "defaults + options" : config_file,
            config.to_string());

  const sigset_t signals = block_stop_signals();
  try {
    return run(config, *key, log, signals);
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    return kExitRuntime;
  }
}
