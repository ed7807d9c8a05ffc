// quad-control's configuration: one JSON file (config/quad-control.json documents every key and
// its default). Absent keys keep the defaults below; unknown keys are errors (typos caught at
// start-up). The loaded configuration is printed at start-up (secret key redacted).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "app/firmware_link.hpp"
#include "app/frame_source.hpp"
#include "app/ground_station.hpp"
#include "record/flight_recorder.hpp"
#include "rgbdquad/receiver/stream_receiver.h"

namespace rgbdquad::quadcontrol {

struct AppConfig {
  // dashboard
  std::string dashboard_bind_address = "127.0.0.1";  ///< loopback: only this machine sees the UI
  std::uint16_t dashboard_port = 8080;
  std::string dashboard_token;  ///< required, and strong (check_token_strength), to bind a
                                ///< non-loopback address
  /// Host names the dashboard answers to besides IP literals and "localhost" (DNS-rebinding guard).
  std::vector<std::string> dashboard_allowed_hosts;
  /// "" = the shipped files, found next to the executable (resolve_data_dirs, app/data_paths.hpp)
  std::string dashboard_static_dir;
  // stream
  std::string stream_source =
      "tum";                ///< "tum" (dataset replay) or "receiver" (rgbd-streamer, live)
  TumReplayOptions replay;  ///< folder "" = the shipped excerpt, found like dashboard_static_dir
  receiver::ReceiverOptions
      receiver;  ///< bind address and RGB/depth ports (offboard/receiver defaults)
  /// The craft's stream key file (stream.key_file; mode 0600, the streamer's stream_key_file):
  /// read when the config is loaded into receiver.key; required for stream.source "receiver".
  std::string stream_key_file;
  // SLAM link: station.slam_mode / station.slam_server
  // firmware
  bool firmware_enabled = true;
  FirmwareLinkOptions firmware;
  std::string firmware_key_hex;  ///< 32 hex digits, the craft's SipHash key (same as provisioned)
  // The control link's ranges and routes are compiled in (generated_control_spec()): no spec file.
  // control + map
  GroundStationOptions station;
  // MCAP flight recorder (section "recording"; docs/recording.md). "~/" in dir = $HOME.
  RecorderOptions recording;

  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
  nlohmann::json to_json_redacted() const;
};

/// Reads `path` over the defaults; nullopt with `error` naming the bad key. Data folders left ""
/// stay "" (resolve_data_dirs fills them in).
std::optional<AppConfig> load_app_config(const std::string& path, std::string* error);
/// Defaults only (no file).
AppConfig default_app_config();

/// Fills the data folders left "" with the shipped ones found relative to `exe_path`
/// (find_data_dir): the dashboard's static files always, the replay excerpt only when the stream
/// is a TUM replay. False with `error` naming every path tried when one is missing.
bool resolve_data_dirs(AppConfig& config, const std::filesystem::path& exe_path,
                       const std::function<bool(const std::filesystem::path&)>& is_file,
                       std::string* error);

}  // namespace rgbdquad::quadcontrol
