// YAML loading, validation and printing of StreamerConfig.
#include "rgbdquad/app/streamer_config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

namespace rgbdquad::app {
namespace {

template <typename T>
void read(const YAML::Node& node, const std::string& key, T* out) {
  try {
    *out = node.as<T>();
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("key '" + key + "': " + e.msg);
  }
}

template <std::size_t N>
void read_array(const YAML::Node& node, const std::string& key, std::array<double, N>* out) {
  if (!node.IsSequence() || node.size() != N) {
    throw std::runtime_error("key '" + key + "': expected a list of " + std::to_string(N) +
                             " numbers");
  }
  for (std::size_t i = 0; i < N; ++i) read(node[i], key, &(*out)[i]);
}

template <std::size_t N>
std::string join(const std::array<double, N>& values) {
  std::ostringstream s;
  s << "[";
  for (std::size_t i = 0; i < N; ++i) s << (i ? ", " : "") << values[i];
  s << "]";
  return s.str();
}

bool all_finite(const double* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) return false;
  }
  return true;
}

}  // namespace

void load_yaml_file(const std::string& path, StreamerConfig* c) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("config " + path + ": " + e.what());
  }
  if (root.IsNull()) return;  // empty file: all defaults
  if (!root.IsMap()) throw std::runtime_error("config " + path + ": top level must be a mapping");
  try {
    for (const auto& entry : root) {
      const std::string key = entry.first.as<std::string>();
      const YAML::Node& v = entry.second;
      if (key == "source")
        read(v, key, &c->source);
      else if (key == "freenect_device_index")
        read(v, key, &c->freenect_device_index);
      else if (key == "freenect_disparity_depth")
        read(v, key, &c->freenect_disparity_depth);
      else if (key == "openni2_uri")
        read(v, key, &c->openni2_uri);
      else if (key == "tum_directory")
        read(v, key, &c->tum_directory);
      else if (key == "tum_fps")
        read(v, key, &c->tum_fps);
      else if (key == "tum_loop")
        read(v, key, &c->tum_loop);
      else if (key == "tum_preload")
        read(v, key, &c->tum_preload);
      else if (key == "max_frames")
        read(v, key, &c->max_frames);
      else if (key == "host")
        read(v, key, &c->host);
      else if (key == "stream_key_file")
        read(v, key, &c->stream_key_file);
      else if (key == "rgb_port")
        read(v, key, &c->rgb_port);
      else if (key == "depth_port")
        read(v, key, &c->depth_port);
      else if (key == "depth_encoding")
        read(v, key, &c->depth_encoding);
      else if (key == "rgb_encoding")
        read(v, key, &c->rgb_encoding);
      else if (key == "jpeg_quality")
        read(v, key, &c->jpeg_quality);
      else if (key == "zstd_level")
        read(v, key, &c->zstd_level);
      else if (key == "pair_depth_with_rgb")
        read(v, key, &c->pair_depth_with_rgb);
      else if (key == "device_id")
        read(v, key, &c->device_id);
      else if (key == "rgb_intrinsics")
        read_array(v, key, &c->rgb_intrinsics);
      else if (key == "rgb_distortion")
        read_array(v, key, &c->rgb_distortion);
      else if (key == "registration_enabled")
        read(v, key, &c->registration_enabled);
      else if (key == "depth_intrinsics")
        read_array(v, key, &c->depth_intrinsics);
      else if (key == "R_rgb_depth")
        read_array(v, key, &c->R_rgb_depth);
      else if (key == "t_rgb_depth_m")
        read_array(v, key, &c->t_rgb_depth_m);
      else if (key == "rgb_black_level")
        read(v, key, &c->rgb_black_level);
      else if (key == "stats_period_s")
        read(v, key, &c->stats_period_s);
      else if (key == "log_level")
        read(v, key, &c->log_level);
      else if (key == "exit_linger_ms")
        read(v, key, &c->exit_linger_ms);
      else
        throw std::runtime_error("unknown key '" + key + "'");
    }
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("config " + path + ": " + e.what());
  }
}

bool StreamerConfig::is_valid(std::string* error) const {
  static const std::set<std::string> kSources = {"freenect", "openni2", "tum"};
  static const std::set<std::string> kDepth = {"raw", "rvl", "zstd-delta"};
  static const std::set<std::string> kRgb = {"raw", "jpeg"};
  static const std::set<std::string> kLevels = {"trace", "debug", "info", "warn", "error"};
  if (!kSources.count(source))
    *error = "source must be freenect, openni2 or tum";
  else if (source == "tum" && tum_directory.empty())
    *error = "source tum needs tum_directory";
  else if (!std::isfinite(tum_fps) || tum_fps > 1000)
    *error = "tum_fps must be finite and <= 1000";
  else if (freenect_device_index < 0)
    *error = "freenect_device_index must be >= 0";
  else if (host.empty())
    *error = "host is empty";
  else if (stream_key_file.empty())
    *error = "stream_key_file is empty (the receiver accepts only a signed handshake)";
  else if (rgb_port == 0 || depth_port == 0 || rgb_port == depth_port)
    *error = "rgb_port and depth_port must be distinct and non-zero";
  else if (!kDepth.count(depth_encoding))
    *error = "depth_encoding must be raw, rvl or zstd-delta";
  else if (!kRgb.count(rgb_encoding))
    *error = "rgb_encoding must be raw or jpeg";
  else if (jpeg_quality < 1 || jpeg_quality > 100)
    *error = "jpeg_quality must be 1..100";
  else if (zstd_level < 1 || zstd_level > 19)
    *error = "zstd_level must be 1..19";
  else if (device_id.empty() || device_id.size() > 255)
    *error = "device_id must be 1..255 characters";
  else if (!all_finite(rgb_intrinsics.data(), 4) || rgb_intrinsics[0] < 1 || rgb_intrinsics[1] < 1)
    *error = "rgb_intrinsics must be finite with fx, fy >= 1";
  else if (!all_finite(rgb_distortion.data(), 5))
    *error = "rgb_distortion must be finite";
  else if (!all_finite(depth_intrinsics.data(), 4) || depth_intrinsics[0] < 1 ||
           depth_intrinsics[1] < 1)
    *error = "depth_intrinsics must be finite with fx, fy >= 1";
  else if (!all_finite(R_rgb_depth.data(), 9) || !all_finite(t_rgb_depth_m.data(), 3))
    *error = "R_rgb_depth and t_rgb_depth_m must be finite";
  else if (rgb_black_level < 0 || rgb_black_level > 254)
    *error = "rgb_black_level must be 0..254";
  else if (!std::isfinite(stats_period_s) || stats_period_s < 0)
    *error = "stats_period_s must be >= 0";
  else if (!kLevels.count(log_level))
    *error = "log_level must be trace, debug, info, warn or error";
  else if (exit_linger_ms < 0 || exit_linger_ms > 60000)
    *error = "exit_linger_ms must be 0..60000";
  else
    return true;
  return false;
}

std::string StreamerConfig::to_string() const {
  std::ostringstream s;
  s << "source: " << source << "\n"
    << "freenect_device_index: " << freenect_device_index << "\n"
    << "freenect_disparity_depth: " << (freenect_disparity_depth ? "true" : "false") << "\n"
    << "openni2_uri: \"" << openni2_uri << "\"\n"
    << "tum_directory: \"" << tum_directory << "\"\n"
    << "tum_fps: " << tum_fps << "\n"
    << "tum_loop: " << (tum_loop ? "true" : "false") << "\n"
    << "tum_preload: " << (tum_preload ? "true" : "false") << "\n"
    << "max_frames: " << max_frames << "\n"
    << "host: " << host << "\n"
    << "rgb_port: " << rgb_port << "\n"
    << "depth_port: " << depth_port << "\n"
    << "stream_key_file: " << stream_key_file << "\n"
    << "depth_encoding: " << depth_encoding << "\n"
    << "rgb_encoding: " << rgb_encoding << "\n"
    << "jpeg_quality: " << jpeg_quality << "\n"
    << "zstd_level: " << zstd_level << "\n"
    << "pair_depth_with_rgb: " << (pair_depth_with_rgb ? "true" : "false") << "\n"
    << "device_id: " << device_id << "\n"
    << "rgb_intrinsics: " << join(rgb_intrinsics) << "\n"
    << "rgb_distortion: " << join(rgb_distortion) << "\n"
    << "registration_enabled: " << (registration_enabled ? "true" : "false") << "\n"
    << "depth_intrinsics: " << join(depth_intrinsics) << "\n"
    << "R_rgb_depth: " << join(R_rgb_depth) << "\n"
    << "t_rgb_depth_m: " << join(t_rgb_depth_m) << "\n"
    << "rgb_black_level: " << rgb_black_level << "\n"
    << "stats_period_s: " << stats_period_s << "\n"
    << "log_level: " << log_level << "\n"
    << "exit_linger_ms: " << exit_linger_ms << "\n";
  return s.str();
}

}  // namespace rgbdquad::app
