// Where quad-control's RGB-D frames come from. The live source is the onboard streamer through the
// ground-station receiver library (offboard/receiver, not landed yet when this was written); the
// dataset source replays a TUM RGB-D folder with its original timing, so the whole ground station
// (SLAM, control, dashboard) runs on real frames without the craft.
// next() blocks until the next frame is due; it is called from one thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "record/encoded_image.hpp"
#include "slam/core/types.hpp"
#include "slam/dataset/tum_dataset.hpp"
#include "slam/motion/accel_gate.hpp"

namespace rgbdquad::quadcontrol {

/// One registered RGB-D frame as it reached the ground station.
struct CameraFrame {
  std::int64_t sequence = 0;     ///< +1 per delivered frame
  std::int64_t capture_us = 0;   ///< sensor clock (dataset timestamp)
  std::int64_t received_us = 0;  ///< ground-station monotonic clock
  double link_latency_ms = 0.0;  ///< time the frame spent on its link (replay: load + decode time)
  cv::Mat rgb;                   ///< CV_8UC3, BGR
  cv::Mat depth;                 ///< CV_16UC1, intrinsics.depth_units_per_m units, 0 = none
  slam::Intrinsics intrinsics;
  /// The link's payloads when the stream was encoded (live source; empty for the dataset replay),
  /// for the flight recorder to store without re-encoding.
  EncodedImage rgb_encoded, depth_encoded;
  /// The camera's NED attitude at capture from the craft's IMU (CraftPoseTracker::
  /// camera_attitude_at), set by the ground station when `camera.imu_rotation_prior` is on; the
  /// SLAM (either link) predicts rotation from it (slam::RgbdFrame::q_nav_cam).
  std::optional<Eigen::Quaterniond> q_ned_cam;
  /// The Kinect's accelerometer sample sent with the colour image (sensor axes, stamp on the
  /// capture clock in seconds), when the source has one; either SLAM link passes it through its
  /// gate into slam::RgbdFrame::accel_cam_mps2.
  std::optional<slam::AccelSample> accel;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Blocks until the next frame (or `stop` becomes true: nullopt, error empty). On a failure
  /// returns nullopt with `error` set.
  virtual std::optional<CameraFrame> next(const std::atomic<bool>& stop, std::string* error) = 0;
  virtual std::string describe() const = 0;
};

enum class ReplayLoop { kOnce, kWrap, kBounce };
bool parse_replay_loop(const std::string& name, ReplayLoop* out);

struct TumReplayOptions {
  std::string folder;
  ReplayLoop loop =
      ReplayLoop::kBounce;     ///< bounce: forward then backward, no jump for the tracker
  double speed = 1.0;          ///< 1 = original timing
  std::string camera = "fr1";  ///< TUM intrinsics name
};

class TumReplaySource : public FrameSource {
 public:
  /// Fails (nullptr, error set) for a missing/unreadable folder.
  static std::unique_ptr<TumReplaySource> open(const TumReplayOptions& options, std::string* error);
  std::optional<CameraFrame> next(const std::atomic<bool>& stop, std::string* error) override;
  std::string describe() const override;

 private:
  TumReplaySource(TumReplayOptions options, slam::TumDataset dataset, slam::Intrinsics intrinsics);
  TumReplayOptions options_;
  slam::TumDataset dataset_;
  slam::Intrinsics intrinsics_;
  std::int64_t delivered_ = 0;
  std::int64_t position_ = 0;
  int direction_ = 1;
  std::optional<std::int64_t> next_due_us_;
};

/// Monotonic clock of the app (the only place quad-control reads time; logic gets it passed in).
std::int64_t monotonic_now_us();

}  // namespace rgbdquad::quadcontrol
