// quad-control configuration loading: see app_config.hpp.
#include "app/app_config.hpp"

#include <cstdlib>
#include <fstream>
#include <set>

#include "app/data_paths.hpp"
#include "app/http_server.hpp"
#include "app/request_guard.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {

using nlohmann::json;

bool check_keys(const json& obj, const std::string& section, const std::set<std::string>& allowed,
                std::string* error) {
  if (!obj.is_object()) {
    *error = section + ": expected an object";
    return false;
  }
  for (const auto& [k, v] : obj.items()) {
    (void)v;
    if (!allowed.count(k)) {
      *error = section + "." + k + ": unknown key";
      return false;
    }
  }
  return true;
}

template <typename T>
bool read(const json& obj, const std::string& section, const char* key, T& out,
          std::string* error) {
  if (!obj.contains(key)) return true;
  try {
    out = obj.at(key).get<T>();
    return true;
  } catch (const std::exception&) {
    *error = section + "." + key + ": wrong type";
    return false;
  }
}

bool read_recording(const json& r, RecorderOptions& o, std::string* error) {
  const char* s = "recording";
  if (!check_keys(
          r, s,
          {"enabled", "dir", "image_every_n_frames", "depth_preview_every_n_frames", "jpeg_quality",
           "map_period_ms", "map_max_points", "flush_period_ms", "max_file_mb", "max_total_mb",
           "queue_max_events", "queue_max_frames", "queue_max_mb", "zstd"},
          error) ||
      !read(r, s, "enabled", o.enabled, error) || !read(r, s, "dir", o.dir, error) ||
      !read(r, s, "image_every_n_frames", o.image_every_n_frames, error) ||
      !read(r, s, "depth_preview_every_n_frames", o.depth_preview_every_n_frames, error) ||
      !read(r, s, "jpeg_quality", o.jpeg_quality, error) ||
      !read(r, s, "map_period_ms", o.map_period_ms, error) ||
      !read(r, s, "map_max_points", o.map_max_points, error) ||
      !read(r, s, "flush_period_ms", o.flush_period_ms, error) ||
      !read(r, s, "max_file_mb", o.max_file_mb, error) ||
      !read(r, s, "max_total_mb", o.max_total_mb, error) ||
      !read(r, s, "queue_max_events", o.queue_max_events, error) ||
      !read(r, s, "queue_max_frames", o.queue_max_frames, error) ||
      !read(r, s, "queue_max_mb", o.queue_max_mb, error) || !read(r, s, "zstd", o.zstd, error)) {
    return false;
  }
  if (o.dir.rfind("~/", 0) == 0) {
    const char* home = std::getenv("HOME");
    if (home != nullptr) o.dir = std::string(home) + o.dir.substr(1);
  }
  return true;
}

}  // namespace

AppConfig default_app_config() { return AppConfig{}; }

bool resolve_data_dirs(AppConfig& config, const std::filesystem::path& exe_path,
                       const std::function<bool(const std::filesystem::path&)>& is_file,
                       std::string* error) {
  if (config.dashboard_static_dir.empty()) {
    const auto dir = find_data_dir(exe_path, kDashboardStaticDir, is_file, error);
    if (!dir) return false;
    config.dashboard_static_dir = dir->string();
  }
  if (config.stream_source == "tum" && config.replay.folder.empty()) {
    const auto dir = find_data_dir(exe_path, kDefaultReplayDir, is_file, error);
    if (!dir) return false;
    config.replay.folder = dir->string();
  }
  return true;
}

bool AppConfig::is_valid(std::string* error) const {
  if (dashboard_port == 0) return reject(error, "dashboard.port must be > 0");
  if (!is_loopback_address(dashboard_bind_address)) {
    if (dashboard_token.empty()) {
      return reject(
          error, "dashboard.bind_address " + dashboard_bind_address +
                     " is not loopback: set dashboard.token (or --token) to expose the dashboard");
    }
    if (const std::string e = check_token_strength(dashboard_token); !e.empty())
      return reject(error, "dashboard.token: " + e);
  }
  if (stream_source != "tum" && stream_source != "receiver") {
    return reject(error, "stream.source must be 'tum' or 'receiver', not '" + stream_source + "'");
  }
  if (stream_source == "receiver") {
    std::string e;
    if (!receiver.is_valid(&e)) return reject(error, "stream: " + e);
  }
  if (firmware_enabled) {
    if (!firmware.is_valid(error)) return false;
    if (firmware_key_hex.empty())
      return reject(
          error,
          "firmware.key_hex is empty: set the craft's 32-hex-digit key (or disable the firmware "
          "link)");
  }
  if (!recording.is_valid(error)) return false;
  return station.is_valid(error);
}

nlohmann::json AppConfig::to_json_redacted() const {
  return {{"dashboard",
           {{"bind_address", dashboard_bind_address},
            {"port", dashboard_port},
            {"token", dashboard_token.empty() ? "" : "<set>"},
            {"static_dir", dashboard_static_dir},
            {"allowed_hosts", dashboard_allowed_hosts}}},
          {"stream",
           {{"source", stream_source},
            {"tum_folder", replay.folder},
            {"speed", replay.speed},
            {"camera", replay.camera},
            {"bind_address", receiver.bind_address},
            {"rgb_port", receiver.rgb_port},
            {"depth_port", receiver.depth_port},
            {"key_file", stream_key_file}}},
          {"slam",
           {{"mode", station.slam_mode},
            {"host", station.slam_server.host},
            {"port", station.slam_server.port},
            {"timeout_ms", station.slam_server.reply_timeout_ms}}},
          {"firmware",
           {{"enabled", firmware_enabled},
            {"host", firmware.host},
            {"port", firmware.port},
            {"timeout_ms", firmware.timeout_ms},
            {"period_ms", firmware.period_ms},
            {"send_on_pose", firmware.send_on_pose},
            {"min_interval_ms", firmware.min_interval_ms},
            {"keep_alive_ms", firmware.keep_alive_ms},
            {"key_hex", firmware_key_hex.empty() ? "" : "<redacted>"}}},
          {"camera",
           {{"mount_pitch_down_deg", station.mount_pitch_down_deg},
            {"imu_rotation_prior", station.imu_rotation_prior}}},
          {"realtime",
           {{"policy", slam::to_string(station.realtime.policy)},
            {"priority", station.realtime.rt_priority},
            {"fallback_nice", station.realtime.fallback_nice}}},
          {"controller", to_json(station.controller)},
          {"recording", recording.to_json()}};
}

namespace {
/// The "dashboard" section into `c`; false with `error` at its first bad key.
bool read_dashboard_section(const json& d, AppConfig& c, std::string* error) {
  return check_keys(d, "dashboard",
                    {"bind_address", "port", "token", "static_dir", "allowed_hosts"}, error) &&
         read(d, "dashboard", "allowed_hosts", c.dashboard_allowed_hosts, error) &&
         read(d, "dashboard", "bind_address", c.dashboard_bind_address, error) &&
         read(d, "dashboard", "port", c.dashboard_port, error) &&
         read(d, "dashboard", "token", c.dashboard_token, error) &&
         read(d, "dashboard", "static_dir", c.dashboard_static_dir, error);
}

/// The "stream" section into `c`; false with `error` at its first bad key.
bool read_stream_section(const json& s, AppConfig& c, std::string& loop, std::string* error) {
  return check_keys(s, "stream",
                    {"source", "tum_folder", "loop", "speed", "camera", "bind_address", "rgb_port",
                     "depth_port", "key_file"},
                    error) &&
         read(s, "stream", "key_file", c.stream_key_file, error) &&
         read(s, "stream", "bind_address", c.receiver.bind_address, error) &&
         read(s, "stream", "rgb_port", c.receiver.rgb_port, error) &&
         read(s, "stream", "depth_port", c.receiver.depth_port, error) &&
         read(s, "stream", "source", c.stream_source, error) &&
         read(s, "stream", "tum_folder", c.replay.folder, error) &&
         read(s, "stream", "loop", loop, error) &&
         read(s, "stream", "speed", c.replay.speed, error) &&
         read(s, "stream", "camera", c.replay.camera, error);
}

/// The "slam" section into `c`; false with `error` at its first bad key.
bool read_slam_section(const json& sl, AppConfig& c, std::string* error) {
  return check_keys(sl, "slam", {"mode", "host", "port", "timeout_ms"}, error) &&
         read(sl, "slam", "mode", c.station.slam_mode, error) &&
         read(sl, "slam", "host", c.station.slam_server.host, error) &&
         read(sl, "slam", "port", c.station.slam_server.port, error) &&
         read(sl, "slam", "timeout_ms", c.station.slam_server.reply_timeout_ms, error);
}

/// The "firmware" section into `c`; false with `error` at its first bad key.
bool read_firmware_section(const json& f, AppConfig& c, std::string* error) {
  return check_keys(f, "firmware",
                    {"enabled", "host", "port", "timeout_ms", "period_ms", "send_on_pose",
                     "min_interval_ms", "keep_alive_ms", "key_hex"},
                    error) &&
         read(f, "firmware", "enabled", c.firmware_enabled, error) &&
         read(f, "firmware", "host", c.firmware.host, error) &&
         read(f, "firmware", "port", c.firmware.port, error) &&
         read(f, "firmware", "timeout_ms", c.firmware.timeout_ms, error) &&
         read(f, "firmware", "period_ms", c.firmware.period_ms, error) &&
         read(f, "firmware", "send_on_pose", c.firmware.send_on_pose, error) &&
         read(f, "firmware", "min_interval_ms", c.firmware.min_interval_ms, error) &&
         read(f, "firmware", "keep_alive_ms", c.firmware.keep_alive_ms, error) &&
         read(f, "firmware", "key_hex", c.firmware_key_hex, error);
}

/// The "camera" section into `c`; false with `error` at its first bad key.
bool read_camera_section(const json& cam, AppConfig& c, std::string* error) {
  return check_keys(cam, "camera", {"mount_pitch_down_deg", "imu_rotation_prior"}, error) &&
         read(cam, "camera", "mount_pitch_down_deg", c.station.mount_pitch_down_deg, error) &&
         read(cam, "camera", "imu_rotation_prior", c.station.imu_rotation_prior, error);
}

/// The "floor" section into `c`; false with `error` at its first bad key.
bool read_floor_section(const json& fl, AppConfig& c, std::string* error) {
  return check_keys(fl, "floor",
                    {"iterations", "inlier_distance_m", "max_tilt_deg", "min_inlier_fraction",
                     "seed", "search_frames"},
                    error) &&
         read(fl, "floor", "iterations", c.station.floor.iterations, error) &&
         read(fl, "floor", "inlier_distance_m", c.station.floor.inlier_distance_m, error) &&
         read(fl, "floor", "max_tilt_deg", c.station.floor.max_tilt_deg, error) &&
         read(fl, "floor", "min_inlier_fraction", c.station.floor.min_inlier_fraction, error) &&
         read(fl, "floor", "seed", c.station.floor.seed, error) &&
         read(fl, "floor", "search_frames", c.station.floor_search_frames, error);
}

/// The "map" section into `c`; false with `error` at its first bad key.
bool read_map_section(const json& m, AppConfig& c, std::string* error) {
  return check_keys(m, "map", {"resolution_m", "size_m", "max_depth_m"}, error) &&
         read(m, "map", "resolution_m", c.station.map.resolution_m, error) &&
         read(m, "map", "size_m", c.station.map.size_m, error) &&
         read(m, "map", "max_depth_m", c.station.max_depth_m, error);
}

/// The "realtime" section into `c`; false with `error` at its first bad key.
bool read_realtime_section(const json& rt, AppConfig& c, std::string& thread_policy,
                           std::string* error) {
  return check_keys(rt, "realtime", {"policy", "priority", "fallback_nice"}, error) &&
         read(rt, "realtime", "policy", thread_policy, error) &&
         read(rt, "realtime", "priority", c.station.realtime.rt_priority, error) &&
         read(rt, "realtime", "fallback_nice", c.station.realtime.fallback_nice, error);
}
}  // namespace

std::optional<AppConfig> load_app_config(const std::string& path, std::string* error) {
  AppConfig c = default_app_config();
  std::ifstream in(path);
  if (!in) {
    *error = "cannot read config file " + path;
    return std::nullopt;
  }
  const json j = json::parse(in, nullptr, false, true);
  if (j.is_discarded()) {
    *error = "config file " + path + " is not valid JSON";
    return std::nullopt;
  }
  if (!check_keys(j, "config",
                  {"about", "dashboard", "stream", "slam", "firmware", "camera", "floor", "map",
                   "controller", "realtime", "recording"},
                  error)) {
    return std::nullopt;
  }
  const json empty = json::object();
  const json& d = j.value("dashboard", empty);
  const json& s = j.value("stream", empty);
  const json& sl = j.value("slam", empty);
  const json& f = j.value("firmware", empty);
  const json& cam = j.value("camera", empty);
  const json& fl = j.value("floor", empty);
  const json& m = j.value("map", empty);
  const json& rt = j.value("realtime", empty);
  if (f.is_object() && f.contains("control_spec")) {
    // Not read any more: the ranges and routes are compiled in from the generated
    // contract, the same the firmware is built with; a file could only disagree with both.
    *error =
        "firmware.control_spec: no longer read - the control link's ranges and routes are compiled "
        "in "
        "(generated from protocol/control/control_spec.json); delete the key";
    return std::nullopt;
  }
  std::string loop = "bounce";
  std::string thread_policy = slam::to_string(c.station.realtime.policy);
  if (!(read_dashboard_section(d, c, error) && read_stream_section(s, c, loop, error) &&
        read_slam_section(sl, c, error) && read_firmware_section(f, c, error) &&
        read_camera_section(cam, c, error) && read_floor_section(fl, c, error) &&
        read_map_section(m, c, error) && read_realtime_section(rt, c, thread_policy, error))) {
    return std::nullopt;
  }
  if (!slam::parse_thread_policy(thread_policy, &c.station.realtime.policy, error)) {
    *error = "realtime.policy: " + *error;
    return std::nullopt;
  }
  if (!read_recording(j.value("recording", empty), c.recording, error)) return std::nullopt;
  if (!c.stream_key_file.empty()) {
    const auto key = protocol::load_stream_key_file(c.stream_key_file, error);
    if (!key) {
      *error = "stream.key_file: " + *error;
      return std::nullopt;
    }
    c.receiver.key = *key;
  }
  if (!parse_replay_loop(loop, &c.replay.loop)) {
    *error = "stream.loop must be once, wrap or bounce";
    return std::nullopt;
  }
  if (j.contains("controller")) {
    const std::string e = load_control_config(j["controller"], c.station.controller);
    if (!e.empty()) {
      *error = e;
      return std::nullopt;
    }
  }
  return c;
}

}  // namespace rgbdquad::quadcontrol
