// Dataset replay input: a TUM RGB-D folder (rgb.txt, depth.txt, optional groundtruth.txt,
// accelerometer.txt and attitude.txt). Each colour image is associated with the nearest depth image
// within `max_dt_s` (20 ms, the benchmark's own rule); a frame-rate reduction r = 1/k keeps every
// k-th associated frame. Each frame also gets the accelerometer sample nearest its colour stamp,
// however far: whether it is usable (fresh, finite, unsaturated) is slam::AccelGate's decision at
// load(). Pacing (real time or as fast as possible) is the caller's business: this class only
// indexes and loads, and never reads the clock.
//
// Thread safety: const methods may be called from several threads.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "slam/core/types.hpp"
#include "slam/motion/accel_gate.hpp"

namespace rgbdquad::slam {

struct TumEntry {
  double rgb_stamp_s = 0;
  std::string rgb_path;  ///< absolute or relative to the working directory
  double depth_stamp_s = 0;
  std::string depth_path;
  /// The accelerometer.txt sample nearest rgb_stamp_s (raw, sensor axes); none without the file.
  std::optional<AccelSample> accel;
  /// The attitude.txt line at rgb_stamp_s (within max_dt_s): the camera's attitude in a
  /// gravity-aligned navigation frame as the flight gave it to SLAM (RgbdFrame::q_nav_cam).
  std::optional<Eigen::Quaterniond> q_nav_cam;
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
  /// Path of accelerometer.txt when it exists, else empty.
  const std::string& accelerometer_path() const { return accelerometer_path_; }
  /// Samples read from accelerometer.txt (0 without the file).
  std::size_t accel_sample_count() const { return accel_sample_count_; }
  /// Path of attitude.txt when it exists, else empty; frames that got an attitude from it.
  const std::string& attitude_path() const { return attitude_path_; }
  std::size_t attitude_frames() const { return attitude_frames_; }
  /// Nominal frame period after rate reduction (median of stamp differences), seconds.
  double frame_period_s() const { return frame_period_s_; }

  /// Loads frame i (colour + 16-bit depth). Fails with a message naming the unreadable file.
  /// With a gate, the frame's accelerometer sample goes through it (AccelGate::attach at the
  /// colour stamp: accel_cam_mps2 set when accepted, the verdict counted); without, the frame
  /// carries no accelerometer sample. The gate is the caller's and must not be shared by threads.
  std::optional<RgbdFrame> load(std::size_t i, std::string* error, AccelGate* gate = nullptr) const;

 private:
  std::string folder_;
  std::string groundtruth_path_;
  std::string accelerometer_path_;
  std::size_t accel_sample_count_ = 0;
  std::string attitude_path_;
  std::size_t attitude_frames_ = 0;
  std::vector<TumEntry> entries_;
  double frame_period_s_ = 1.0 / 30.0;
  bool stamp_from_depth_ = true;
};

/// Parses "timestamp filename" lines (comments '#' and blank lines skipped).
bool read_tum_list(const std::string& path, std::vector<std::pair<double, std::string>>* out,
                   std::string* error);

/// One line of attitude.txt.
struct AttitudeSample {
  double stamp_s = 0;
  Eigen::Quaterniond q_nav_cam = Eigen::Quaterniond::Identity();
};
/// Parses attitude.txt, written by flight_recording.replay from a flight recording: "timestamp qx
/// qy qz qw" lines (the camera's attitude in the flight controller's NED frame at the colour
/// stamp, as quad-control gave it to SLAM; comments '#' and blank lines skipped). A non-finite or
/// zero-length quaternion is a malformed line; the others are normalised. Sorted by stamp.
bool read_attitude_file(const std::string& path, std::vector<AttitudeSample>* out,
                        std::string* error);

/// Parses TUM accelerometer.txt: "timestamp ax ay az" lines (m/s^2, the sensor's axes; comments
/// '#' and blank lines skipped), sorted by stamp. Values may be nan/inf (kept: the gate refuses
/// them); a line that is not four numbers or has a non-finite stamp fails with its line number.
bool read_tum_accelerometer(const std::string& path, std::vector<AccelSample>* out,
                            std::string* error);

/// The sample of `sorted` (by stamp) nearest stamp_s; nullopt when `sorted` is empty.
std::optional<AccelSample> nearest_accel_sample(const std::vector<AccelSample>& sorted,
                                                double stamp_s);

}  // namespace rgbdquad::slam
