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

int main(int argc, char** argv) {
  CLI::App cli{
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
      "engine's front-end inside quad-control, odometry only)."};
  std::string config_path, bind_address, token, tum_folder, firmware_host, key_hex;
  int port = -1, firmware_port = -1;
  bool no_firmware = false, print_config = false;
  cli.add_option("-c,--config", config_path, "JSON config file (default: built-in defaults)");
  cli.add_option("--bind", bind_address,
                 "dashboard address (default 127.0.0.1; non-loopback needs --token)");
  cli.add_option("--port", port, "dashboard TCP port (default 8080; 0 = any free port, printed)");
  cli.add_option("--token", token, "dashboard access token (required for a non-loopback --bind)");
  cli.add_option(
      "--tum", tum_folder,
      "replay this TUM RGB-D folder as the camera (sets stream.source=tum; default: the shipped "
      "fr1_xyz_first30 excerpt)");
  bool live = false;
  cli.add_flag("--live", live, "take frames from rgbd-streamer (sets stream.source=receiver)");
  cli.add_option("--firmware-host", firmware_host, "firmware (WiFi bridge) address");
  cli.add_option("--firmware-port", firmware_port, "firmware HTTP port");
  cli.add_option("--key", key_hex, "craft control key, 32 hex digits (prefer the config file)");
  std::string slam_mode;
  cli.add_option("--slam", slam_mode, "SLAM link: server (slam-server, default) or in-process");
  cli.add_flag("--no-firmware", no_firmware,
               "do not talk to the firmware (commands are computed only)");
  cli.add_flag("--print-config", print_config, "print the effective configuration and exit");
  std::string flight_log_dir;
  cli.add_option("--flight-log", flight_log_dir,
                 "record frames.csv, poses.csv, trajectory.tum and commands.csv in this folder "
                 "(monotonic us stamps; created if missing)");
  std::string record_dir;
  bool no_record = false;
  cli.add_option(
      "--record", record_dir,
      "record the flight as MCAP in this folder (sets recording.enabled; docs/recording.md)");
  cli.add_flag("--no-record", no_record,
               "do not record MCAP (overrides recording.enabled in the config)");
  CLI11_PARSE(cli, argc, argv);

  std::string error;
  std::optional<AppConfig> config =
      config_path.empty() ? default_app_config() : load_app_config(config_path, &error);
  if (!config) {
    std::cerr << "quad-control: " << error << "\n";
    return 2;
  }
  if (!bind_address.empty()) config->dashboard_bind_address = bind_address;
  if (port >= 0) {
    if (port > 65535) {
      std::cerr << "quad-control: --port must be in [0, 65535]\n";
      return 2;
    }
    config->dashboard_port = static_cast<std::uint16_t>(port);
  }
  if (!token.empty()) config->dashboard_token = token;
  if (!tum_folder.empty()) {
    config->replay.folder = tum_folder;
    config->stream_source = "tum";
  }
  if (live) config->stream_source = "receiver";
  if (!firmware_host.empty()) config->firmware.host = firmware_host;
  if (firmware_port > 0 && firmware_port <= 65535)
    config->firmware.port = static_cast<std::uint16_t>(firmware_port);
  if (!key_hex.empty()) config->firmware_key_hex = key_hex;
  if (no_firmware) config->firmware_enabled = false;
  if (!slam_mode.empty()) config->station.slam_mode = slam_mode;
  if (!record_dir.empty()) {
    config->recording.enabled = true;
    config->recording.dir = record_dir;
  }
  if (no_record) config->recording.enabled = false;
  // Port 0 is accepted on the command line (tests): validate with a placeholder.
  const std::uint16_t wanted_port = config->dashboard_port;
  if (wanted_port == 0) config->dashboard_port = 1;
  if (const std::string e = config->validate(); !e.empty()) {
    std::cerr << "quad-control: invalid configuration: " << e << "\n";
    return 2;
  }
  config->dashboard_port = wanted_port;
  const auto exe = current_executable(&error);
  if (!exe || !resolve_data_dirs(*config, *exe, is_regular_file_noexcept, &error)) {
    std::cerr << "quad-control: " << error << "\n";
    return 2;
  }
  std::cout << "quad-control: configuration " << config->to_json_redacted().dump() << std::endl;
  if (print_config) return 0;

  rgbd_control::Key key{};
  std::optional<FirmwareLinkOptions> firmware;
  if (config->firmware_enabled) {
    auto k = parse_control_key(config->firmware_key_hex, &error);
    if (!k) {
      std::cerr << "quad-control: firmware.key_hex: " << error << "\n";
      return 2;
    }
    key = *k;
    firmware = config->firmware;
  }
  std::unique_ptr<FrameSource> source;
  if (config->stream_source == "tum") {
    source = TumReplaySource::open(config->replay, &error);
  } else {
    try {
      // The receiver's two socket threads are on the real-time path: created while this thread is
      // raised, they inherit its scheduling (offboard/receiver stays free of it).
      const ScopedThreadRaise raised(config->station.realtime,
                                     "stream receiver (its socket threads)");
      source = std::make_unique<ReceiverSource>(config->receiver);
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  if (!source) {
    std::cerr << "quad-control: stream: " << error << "\n";
    return 2;
  }
  std::cout << "quad-control: stream from " << source->describe() << std::endl;

  std::unique_ptr<FlightLog> flight_log;
  if (!flight_log_dir.empty()) {
    flight_log = FlightLog::open(flight_log_dir, &error);
    if (!flight_log) {
      std::cerr << "quad-control: " << error << "\n";
      return 2;
    }
    std::cout << "quad-control: flight log in " << flight_log_dir << std::endl;
  }

  std::unique_ptr<FlightRecorder> recorder;
  if (config->recording.enabled) {
    // A file-size limit (RLIMIT_FSIZE) must fail the write (EFBIG), as a full disk does, not kill
    // the flight.
    std::signal(SIGXFSZ, SIG_IGN);
    char stem[64];
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    gmtime_r(&now, &utc);
    std::strftime(stem, sizeof stem, "flight-%Y%m%d-%H%M%S", &utc);
    recorder = FlightRecorder::open(
        config->recording, stem, [](const std::string& line) { log_line(line); }, &error);
    if (!recorder) {
      std::cerr << "quad-control: " << error << "\n";
      return 2;
    }
    std::cout << "quad-control: recording MCAP to " << recorder->stats().file << std::endl;
  }

  // Block the stop signals before any thread starts so only sigwait below receives them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  try {
    GroundStation station(config->station, std::move(source), firmware, generated_control_spec(),
                          key, std::move(flight_log), std::move(recorder));
    DashboardApi api(station, config->dashboard_static_dir,
                     AccessPolicy{config->dashboard_token, config->dashboard_allowed_hosts},
                     monotonic_now_us);
    HttpServer server(config->dashboard_bind_address, config->dashboard_port,
                      [&api](const HttpRequest& r) { return api.handle(r); });
    // One write for the whole line: the real-time threads log to the same pipe meanwhile, and a
    // line written in pieces was split by one of theirs (a test then could not read the port).
    std::cout << "quad-control: dashboard on http://" + config->dashboard_bind_address + ":" +
                     std::to_string(server.port()) + "/\n"
              << std::flush;
    int sig = 0;
    sigwait(&signals, &sig);
    std::cout << "quad-control: stopping (signal " << sig << ")" << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "quad-control: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
