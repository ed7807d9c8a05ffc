// The newest camera frame and the dashboard's images of it: the RGB as JPEG (quality 80) and the
// depth as a greyscale PNG (near bright, far dark, no reading black), each encoded once per frame
// on first request and dropped when a newer frame arrives. Not thread-safe (the owner guards it).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "app/frame_source.hpp"

namespace rgbdquad::quadcontrol {

class FrameImages {
 public:
  /// Greyscale range of the depth image: 0 m white .. 5 m black (the Kinect's range).
  static constexpr double kDepthDisplayMaxM = 5.0;
  static constexpr int kJpegQuality = 80;

  /// Keeps `frame` as the newest one.
  void set_frame(const CameraFrame& frame) { frame_ = frame; }
  const std::optional<CameraFrame>& frame() const { return frame_; }
  /// Sequence of the newest frame; -1 before the first.
  std::int64_t sequence() const { return frame_ ? frame_->sequence : -1; }
  /// nullopt before the first frame or when encoding fails.
  std::optional<std::string> rgb_jpeg();
  std::optional<std::string> depth_png();

 private:
  /// Drops the encoded images when the newest frame changed since they were encoded.
  void invalidate_if_new_frame();

  std::optional<CameraFrame> frame_;
  std::optional<std::string> rgb_jpeg_, depth_png_;
  std::int64_t encoded_sequence_ = -1;
};

}  // namespace rgbdquad::quadcontrol
