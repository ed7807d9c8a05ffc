// What the dashboard shows of the frame stream: frames received, frame rate (exponential moving
// average of the frame-to-frame rate), the link latency of the newest frame and the source's
// last error. Times in microseconds of the ground station's monotonic clock, passed in.
// Pure; not thread-safe (the owner guards it).
#pragma once

#include <cstdint>
#include <string>

namespace rgbdquad::quadcontrol {

class StreamStats {
 public:
  /// Weight of the newest frame-to-frame rate in the average: smoothed over ~5 frames.
  static constexpr double kFpsEmaWeight = 0.2;

  /// A frame received at `received_us` that spent `link_latency_ms` on its link. A frame not
  /// later than the previous one counts but leaves the rate as it was.
  void on_frame(std::int64_t received_us, double link_latency_ms);
  void set_error(std::string error) { error_ = std::move(error); }

  std::int64_t frames() const { return frames_; }
  double fps() const { return fps_; }
  double latency_ms() const { return latency_ms_; }
  const std::string& error() const { return error_; }

 private:
  std::int64_t frames_ = 0;
  double fps_ = 0.0;
  std::int64_t last_frame_us_ = 0;
  double latency_ms_ = 0.0;
  std::string error_;
};

}  // namespace rgbdquad::quadcontrol
