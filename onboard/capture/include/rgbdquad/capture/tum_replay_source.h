// Replays a TUM RGB-D benchmark folder (rgb.txt, depth.txt, rgb/*.png, depth/*.png; depth 16-bit,
// 5000 units per metre, already registered to RGB) as a capture source. Frames carry the dataset's
// timestamps (so they pair with groundtruth.txt and accelerometer.txt), shifted by the sequence
// span on each loop so they stay increasing.
//
// Pacing: original timing (speed 1), a target RGB frame rate (time scaled so RGB arrives at that
// rate), or unpaced (as fast as the consumer reads; benchmarks).
#pragma once

#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/frame_source.h"

namespace rgbdquad::capture {

struct TumReplayOptions {
  std::string directory;
  // 0 = original timing; > 0 = time-scaled so RGB frames arrive at this rate; < 0 = unpaced.
  double fps = 0.0;
  bool loop = false;
  // Decode every PNG at start-up (the replay then costs no CPU per frame; ~1.5 MB per RGB+depth).
  bool preload = false;
  // Stop after this many frames (RGB + depth); 0 = no limit.
  std::size_t max_frames = 0;

  bool is_valid(std::string* error) const;
};

class TumReplaySource final : public FrameSource {
 public:
  // Reads the index files; throws std::runtime_error with a clear message if the folder is not a
  // TUM sequence (start-up boundary). `clock` must outlive the source.
  TumReplaySource(const TumReplayOptions& options, Clock* clock);
  ~TumReplaySource() override;

  std::optional<SourceFrame> next() override;
  void stop() override { stopped_ = true; }
  std::string error() const override { return error_; }
  std::string describe() const override;

  std::size_t rgb_count() const;
  // Readings in accelerometer.txt (0 when the folder has none).
  std::size_t accel_count() const { return accel_count_; }
  std::size_t depth_count() const;

 private:
  struct Entry {
    std::int64_t timestamp_us;
    bool is_depth;
    std::string path;
    std::optional<AccelReading> accel;  // RGB: accelerometer.txt's nearest reading, dataset time
  };
  std::optional<SourceFrame> load(const Entry& entry, std::int64_t timestamp_us);

  TumReplayOptions options_;
  Clock* clock_;
  std::vector<Entry> entries_;  // merged, time-ordered
  std::size_t accel_count_ = 0;
  std::vector<SourceFrame> preloaded_;
  double time_scale_ = 1.0;   // wall seconds per dataset second
  std::int64_t span_us_ = 0;  // dataset span + one RGB period (loop offset)
  std::size_t cursor_ = 0;
  std::size_t delivered_ = 0;
  std::int64_t loop_offset_us_ = 0;
  std::optional<std::int64_t> start_wall_us_;
  std::atomic<bool> stopped_{false};
  std::string error_;
};

}  // namespace rgbdquad::capture
