// quad-control: the ground-station hub (thesis Section 3.3.3). Wiring only: configuration, links,
// the control loop and the web dashboard; the logic lives in core/, map/ and link/.
#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <memory>

#include "app/app_config.hpp"
#include "app/dashboard_api.hpp"
#include "app/data_paths.hpp"
#include "app/ground_station.hpp"
#include "app/http_server.hpp"
#include "app/log_line.hpp"
#include "app/receiver_source.hpp"
#include "app/thread_setup.hpp"

using namespace rgbdquad::quadcontrol;

namespace {

constexpr int kExitUsage = 2;    // configuration or start-up resources refused
constexpr int kExitRuntime = 1;  // an exception at start-up of the links or the dashboard

constexpr const char* kDescription =
    "quad-control: ground-station control loop and web dashboard.\n"
    "Joins the RGB-D frame source, SLAM, the flight controller (PID position control, take-off / "
    "hold at\n"
    "1.7 m / waypoint / land) and the firmware REST link, and serves the dashboard on\n"
    "http://127.0.0.1:8080/ by default. Every setting and its default is in the config file\n"
    "template (<prefix>/share/rgbdquad/config/quad-control.json when installed,\n"
    "offboard/quadcontrol/config/quad-control.json in the source tree); command-line options\n"
    "override it. The dashboard's files and the default replay are found next to this program:\n"
    "<bin>/../share/rgbdquad/{dashboard,data/fr1_xyz_first30} when installed, else the source\n"
    "tree above a build folder (docs/control.md, Installing).\n"
    "Frame sources: stream.source=receiver (rgbd-streamer, RGB port 5600 / depth port 5601) or\n"
    "tum (TUM dataset replay, the default). SLAM: slam.mode=server (slam-server on\n"
    "127.0.0.1:5700, the default; frames still show while it is down) or in-process (the SLAM\n"
    "engine's front-end inside quad-control, odometry only).";

/// The command line: each option set overrides the configuration file.
struct CommandLine {
  std::string config_path, bind_address, token, tum_folder, firmware_host, key_hex, slam_mode;
  std::string flight_log_dir, record_dir;
  int port = -1, firmware_port = -1;
  bool live = false, no_firmware = false, print_config = false, no_record = false;
};

void add_options(CLI::App& cli, CommandLine& a) {
  cli.add_option("-c,--config", a.config_path, "JSON config file (default: built-in defaults)");
  cli.add_option("--bind", a.bind_address,
                 "dashboard address (default 127.0.0.1; non-loopback needs --token)");
  cli.add_option("--port", a.port, "dashboard TCP port (default 8080; 0 = any free port, printed)");
  cli.add_option("--token", a.token, "dashboard access token (required for a non-loopback --bind)");
  cli.add_option(
      "--tum", a.tum_folder,
      "replay this TUM RGB-D folder as the camera (sets stream.source=tum; default: the shipped "
      "fr1_xyz_first30 excerpt)");
  cli.add_flag("--live", a.live, "take frames from rgbd-streamer (sets stream.source=receiver)");
  cli.add_option("--firmware-host", a.firmware_host, "firmware (WiFi bridge) address");
  cli.add_option("--firmware-port", a.firmware_port, "firmware HTTP port");
  cli.add_option("--key", a.key_hex, "craft control key, 32 hex digits (prefer the config file)");
  cli.add_option("--slam", a.slam_mode, "SLAM link: server (slam-server, default) or in-process");
  cli.add_flag("--no-firmware", a.no_firmware,
               "do not talk to the firmware (commands are computed only)");
  cli.add_flag("--print-config", a.print_config, "print the effective configuration and exit");
  cli.add_option("--flight-log", a.flight_log_dir,
                 "record frames.csv, poses.csv, trajectory.tum and commands.csv in this folder "
                 "(monotonic us stamps; created if missing)");
  cli.add_option(
      "--record", a.record_dir,
      "record the flight as MCAP in this folder (sets recording.enabled; docs/recording.md)");
  cli.add_flag("--no-record", a.no_record,
               "do not record MCAP (overrides recording.enabled in the config)");
}

/// The command line's overrides on `config`; false (with `error`) for an out-of-range --port.
bool apply_overrides(const CommandLine& a, AppConfig& config, std::string* error) {
  if (!a.bind_address.empty()) config.dashboard_bind_address = a.bind_address;
  if (a.port >= 0) {
    if (a.port > 65535) {
      *error = "--port must be in [0, 65535]";
      return false;
    }
    config.dashboard_port = static_cast<std::uint16_t>(a.port);
  }
  if (!a.token.empty()) config.dashboard_token = a.token;
  if (!a.tum_folder.empty()) {
    config.replay.folder = a.tum_folder;
    config.stream_source = "tum";
  }
  if (a.live) config.stream_source = "receiver";
  if (!a.firmware_host.empty()) config.firmware.host = a.firmware_host;
  if (a.firmware_port > 0 && a.firmware_port <= 65535)
    config.firmware.port = static_cast<std::uint16_t>(a.firmware_port);
  if (!a.key_hex.empty()) config.firmware_key_hex = a.key_hex;
  if (a.no_firmware) config.firmware_enabled = false;
  if (!a.slam_mode.empty()) config.station.slam_mode = a.slam_mode;
  if (!a.record_dir.empty()) {
    config.recording.enabled = true;
    config.recording.dir = a.record_dir;
  }
  if (a.no_record) config.recording.enabled = false;
  return true;
}

/// The configuration file (or the defaults) with the command line's overrides, validated, its
/// data folders resolved next to this executable; nullopt with `error` (the line to print).
std::optional<AppConfig> effective_config(const CommandLine& a, std::string* error) {
  std::optional<AppConfig> config =
      a.config_path.empty() ? default_app_config() : load_app_config(a.config_path, error);
  if (!config || !apply_overrides(a, *config, error)) return std::nullopt;
  // Port 0 is accepted on the command line (tests): validate with a placeholder.
  const std::uint16_t wanted_port = config->dashboard_port;
  if (wanted_port == 0) config->dashboard_port = 1;
  if (std::string e; !config->is_valid(&e)) {
    *error = "invalid configuration: " + e;
    return std::nullopt;
  }
  config->dashboard_port = wanted_port;
  const auto exe = current_executable(error);
  if (!exe || !resolve_data_dirs(*config, *exe, is_regular_file_noexcept, error))
    return std::nullopt;
  return config;
}

/// The firmware link's options and key; nullopt options with firmware off. False (with `error`)
/// for a malformed key.
bool firmware_link(const AppConfig& config, std::optional<FirmwareLinkOptions>* firmware,
                   rgbd_control::Key* key, std::string* error) {
  if (!config.firmware_enabled) return true;
  auto k = parse_control_key(config.firmware_key_hex, error);
  if (!k) {
    *error = "firmware.key_hex: " + *error;
    return false;
  }
  *key = *k;
  *firmware = config.firmware;
  return true;
}

std::unique_ptr<FrameSource> open_frame_source(const AppConfig& config, std::string* error) {
  std::unique_ptr<FrameSource> source;
  if (config.stream_source == "tum") {
    source = TumReplaySource::open(config.replay, error);
  } else {
    try {
      // The receiver's two socket threads are on the real-time path: created while this thread is
      // raised, they inherit its scheduling (offboard/receiver stays free of it).
      const ScopedThreadRaise raised(config.station.realtime,
                                     "stream receiver (its socket threads)");
      source = std::make_unique<ReceiverSource>(config.receiver);
    } catch (const std::exception& e) {
      *error = e.what();
    }
  }
  if (!source) *error = "stream: " + *error;
  return source;
}

/// The MCAP recorder, its file named by the UTC start time.
std::unique_ptr<FlightRecorder> open_recorder(const AppConfig& config, std::string* error) {
  // A file-size limit (RLIMIT_FSIZE) must fail the write (EFBIG), as a full disk does, not kill
  // the flight.
  std::signal(SIGXFSZ, SIG_IGN);
  char stem[64];
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::strftime(stem, sizeof stem, "flight-%Y%m%d-%H%M%S", &utc);
  return FlightRecorder::open(
      config.recording, stem, [](const std::string& line) { log_line(line); }, error);
}

/// Everything the station is started with.
struct StationParts {
  std::optional<FirmwareLinkOptions> firmware;
  rgbd_control::Key key{};
  std::unique_ptr<FrameSource> source;
  std::unique_ptr<FlightLog> flight_log;
  std::unique_ptr<FlightRecorder> recorder;
};

/// Opens the links, the flight log and the recorder; false with `error` (the line to print).
bool open_parts(const AppConfig& config, const CommandLine& a, StationParts& parts,
                std::string* error) {
  if (!firmware_link(config, &parts.firmware, &parts.key, error)) return false;
  parts.source = open_frame_source(config, error);
  if (!parts.source) return false;
  std::cout << "quad-control: stream from " << parts.source->describe() << std::endl;
  if (!a.flight_log_dir.empty()) {
    parts.flight_log = FlightLog::open(a.flight_log_dir, error);
    if (!parts.flight_log) return false;
    std::cout << "quad-control: flight log in " << a.flight_log_dir << std::endl;
  }
  if (config.recording.enabled) {
    parts.recorder = open_recorder(config, error);
    if (!parts.recorder) return false;
    std::cout << "quad-control: recording MCAP to " << parts.recorder->stats().file << std::endl;
  }
  return true;
}

/// Starts the station and the dashboard and serves until SIGINT/SIGTERM (blocked in `signals`
/// before any thread started).
int serve_until_signal(AppConfig& config, StationParts parts, sigset_t& signals) {
  try {
    GroundStation station(config.station, std::move(parts.source), parts.firmware,
                          generated_control_spec(), parts.key, std::move(parts.flight_log),
                          std::move(parts.recorder));
    station.start();
    DashboardApi api(station, config.dashboard_static_dir,
                     AccessPolicy{config.dashboard_token, config.dashboard_allowed_hosts},
                     monotonic_now_us);
    HttpServer server(config.dashboard_bind_address, config.dashboard_port,
                      [&api](const HttpRequest& r) { return api.handle(r); });
    // One write for the whole line: the real-time threads log to the same pipe meanwhile, and a
    // line written in pieces was split by one of theirs (a test then could not read the port).
    std::cout << "quad-control: dashboard on http://" + config.dashboard_bind_address + ":" +
                     std::to_string(server.port()) + "/\n"
              << std::flush;
    int sig = 0;
    sigwait(&signals, &sig);
    std::cout << "quad-control: stopping (signal " << sig << ")" << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "quad-control: " << e.what() << "\n";
    return kExitRuntime;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{kDescription};
  CommandLine args;
  add_options(cli, args);
  CLI11_PARSE(cli, argc, argv);

  std::string error;
  std::optional<AppConfig> config = effective_config(args, &error);
  if (!config) {
    std::cerr << "quad-control: " << error << "\n";
    return kExitUsage;
  }
  std::cout << "quad-control: configuration " << config->to_json_redacted().dump() << std::endl;
  if (args.print_config) return 0;

  StationParts parts;
  if (!open_parts(*config, args, parts, &error)) {
    std::cerr << "quad-control: " << error << "\n";
    return kExitUsage;
  }

  // Block the stop signals before any thread starts so only sigwait below receives them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return serve_until_signal(*config, std::move(parts), signals);
}
