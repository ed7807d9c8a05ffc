// Dataset replay input: a TUM RGB-D folder (rgb.txt, depth.txt, optional groundtruth.txt).
// Each colour image is associated with the nearest depth image within `max_dt_s` (20 ms, the
// benchmark's own rule); a frame-rate reduction r = 1/k keeps every k-th associated frame.
// Pacing (real time or as fast as possible) is the caller's business: this class only indexes and
// loads, and never reads the clock.
//
// Thread safety: const methods may be called from several threads.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "slam/core/types.hpp"

namespace slam {

struct TumEntry {
  double rgb_stamp_s = 0;
  std::string rgb_path;  ///< absolute or relative to the working directory
  double depth_stamp_s = 0;
  std::string depth_path;
};

struct TumDatasetOptions {
  double max_dt_s = 0.02;  ///< TUM associate.py default (20 ms)
  int rate_divisor = 1;    ///< keep every k-th frame (k >= 1)
  int max_frames = 0;      ///< 0 = all
  /// Stamp given to a frame: the depth image's (default) or the colour image's. The 3D geometry
  /// every estimate rests on comes from the depth image, so its capture time is the pose's time
  /// (RGBD-SLAM's reference trajectories use it too); fr1 colour and depth differ by up to 17 ms.
  bool stamp_from_depth = true;
  bool is_valid(std::string* error) const;
};

class TumDataset {
 public:
  /// Reads the index files. Fails with a clear message for a missing folder, missing or empty
  /// rgb.txt/depth.txt, malformed lines, or no association within max_dt_s.
  static std::optional<TumDataset> open(const std::string& folder, const TumDatasetOptions& options,
                                        std::string* error);

  std::size_t size() const { return entries_.size(); }
  const TumEntry& entry(std::size_t i) const { return entries_.at(i); }
  const std::string& folder() const { return folder_; }
  /// Path of groundtruth.txt when it exists, else empty.
  const std::string& groundtruth_path() const { return groundtruth_path_; }
  /// Nominal frame period after rate reduction (median of stamp differences), seconds.
  double frame_period_s() const { return frame_period_s_; }

  /// Loads frame i (colour + 16-bit depth). Fails with a message naming the unreadable file.
  std::optional<RgbdFrame> load(std::size_t i, std::string* error) const;

 private:
  std::string folder_;
  std::string groundtruth_path_;
  std::vector<TumEntry> entries_;
  double frame_period_s_ = 1.0 / 30.0;
  bool stamp_from_depth_ = true;
};

/// Parses "timestamp filename" lines (comments '#' and blank lines skipped).
bool read_tum_list(const std::string& path, std::vector<std::pair<double, std::string>>* out,
                   std::string* error);

}  // namespace slam
