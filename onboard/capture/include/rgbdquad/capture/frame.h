// Value types that cross the capture -> validation -> registration -> streaming stages.
// Images are row-major and own their pixels. Timestamps are capture times in microseconds on the
// source's clock (sensor/host monotonic clock for live devices, the dataset's clock for replays),
// so RGB can be paired with depth, and frames with IMU readings that arrive by another route.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "rgbdquad/camera/tum_cameras.hpp"

namespace rgbdquad::capture {

// Kinect v1 native resolution, the size every source in this project delivers.
constexpr int kKinectWidthPx = 640;
constexpr int kKinectHeightPx = 480;
// Depth units: Kinect drivers deliver millimetres; the TUM dataset stores 5000 units per metre
// (protocol/camera/tum_cameras.json, the one definition).
constexpr double kMillimetreUnitsPerM = 1000.0;
constexpr double kTumDepthUnitsPerM = camera::kTumDepthUnitsPerM;

// One reading of the Kinect's accelerometer: specific force (at rest 1 g upwards) in the
// accelerometer's own axes, m/s^2, as libfreenect's freenect_get_mks_accel and TUM's
// accelerometer.txt give it (protocol/camera/tum_cameras.json "accelerometer" maps it to the
// colour camera's frame; the ground station does that).
struct AccelReading {
  std::int64_t capture_timestamp_us = 0;  // same clock as the images'
  std::array<double, 3> f_mps2{};
};

struct RgbFrame {
  std::int64_t capture_timestamp_us = 0;
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;      // width*height*3 bytes, R,G,B
  std::optional<AccelReading> accel;  // the reading nearest this image, when the source has one
};

struct DepthFrame {
  std::int64_t capture_timestamp_us = 0;
  int width = 0;
  int height = 0;
  double units_per_m = kMillimetreUnitsPerM;  // value of depth[i] for a point 1 m away
  bool registered_to_rgb = false;             // true when pixel (u,v) looks at RGB pixel (u,v)
  std::vector<std::uint16_t> depth;           // width*height values, 0 = no reading
};

using SourceFrame = std::variant<RgbFrame, DepthFrame>;

}  // namespace rgbdquad::capture
