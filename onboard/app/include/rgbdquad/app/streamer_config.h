// rgbd-streamer's configuration: one flat struct with in-class defaults, loaded from a YAML file
// (onboard/config/rgbd-streamer.yaml documents every key), overridden by command-line options,
// validated as a whole, and logged as loaded.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "rgbdquad/camera/tum_cameras.hpp"

namespace rgbdquad::app {

struct StreamerConfig {
  // source
  std::string source = "freenect";  // freenect | openni2 | tum
  int freenect_device_index = 0;
  bool freenect_disparity_depth = false;  // true for fakenect dumps (see freenect_source.h)
  std::string openni2_uri;                // empty = first device
  std::string tum_directory;
  double tum_fps = 0.0;  // 0 original timing, > 0 RGB frame rate, < 0 unpaced
  bool tum_loop = true;
  bool tum_preload = false;
  std::uint64_t max_frames = 0;  // stop after this many captured frames; 0 = run forever

  // ground station
  std::string host = "192.168.1.10";
  std::uint16_t rgb_port = 5600;
  std::uint16_t depth_port = 5601;
  // The craft's stream key (32 hex digits, mode 0600; the same file as the ground station's
  // stream.key_file): the receiver accepts only a handshake signed with it (docs/security.md).
  std::string stream_key_file = "/etc/rgbd-streamer/stream.key";

  // encodings (negotiated in the handshake)
  std::string depth_encoding = "rvl";  // raw | rvl | zstd-delta
  std::string rgb_encoding = "raw";    // raw | jpeg
  int jpeg_quality = 90;
  int zstd_level = 1;
  // Send the depth frame nearest in time to the RGB frame just sent (from the 6 newest) instead of
  // strictly the newest: on a slow link the frames that arrive then form RGB-D pairs.
  bool pair_depth_with_rgb = true;

  // camera: intrinsics of the RGB image (what the depth is registered to). Defaults: the usual
  // Kinect v1 colour camera values (fx = fy = 525 px, principal point at the centre: the ROS
  // default model, protocol/camera/tum_cameras.json "ros_default").
  std::string device_id = "kinect-v1";
  std::array<double, 4> rgb_intrinsics{camera::kTumRosDefault.fx_px, camera::kTumRosDefault.fy_px,
                                       camera::kTumRosDefault.cx_px, camera::kTumRosDefault.cy_px};
  std::array<double, 5> rgb_distortion{0, 0, 0, 0, 0};

  // software registration for sources whose driver does not register depth (OpenNI2 devices
  // without hardware registration). Kinect v1 IR camera defaults: fx = fy = 580 px
  // (Khoshelham & Elberink 2012), baseline 25 mm along x.
  bool registration_enabled = true;
  std::array<double, 4> depth_intrinsics{580.0, 580.0, 319.5, 239.5};
  std::array<double, 9> R_rgb_depth{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> t_rgb_depth_m{-0.025, 0.0, 0.0};

  // validation
  int rgb_black_level = 0;

  // operation
  double stats_period_s = 5.0;  // periodic counters line; 0 = off
  std::string log_level = "info";
  // After a replay ends, wait up to this long for the last frames to be requested and sent.
  int exit_linger_ms = 2000;

  bool is_valid(std::string* error) const;
  std::string to_string() const;  // every key and value, one line each, as loaded
};

// Applies the keys present in a YAML file on top of `config`. Throws std::runtime_error naming
// the file, key and problem (unknown keys are errors: a typo must not silently use a default).
void load_yaml_file(const std::string& path, StreamerConfig* config);

}  // namespace rgbdquad::app
