// Flight recorder of quad-control (`--flight-log DIR`): what the ground station saw and did,
// stamped with the monotonic clock in microseconds (the clock rgbd-streamer stamps frames with when
// both run on one machine, as in the HIL rig), for post-flight analysis: ATE of the SLAM trajectory
// against ground truth and the latency of every stage (capture -> received -> pose -> command
// sent).
//   frames.csv      one row per frame received from the source
//   poses.csv       one row per SLAM result (tracked or not), in the floor-aligned world frame
//   trajectory.tum  T_floor_cam of every tracked frame at its capture time (TUM format, seconds)
//   commands.csv    one row per command handed to the firmware link, with the pose it was computed
//   from
// Every row is flushed when written, so a ground station killed mid-flight (HIL scenario 3) keeps
// its log. Thread-safe (one mutex); write errors are counted, never thrown, and never stop the
// flight.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>

#include "core/stick_mapping.hpp"

namespace rgbdquad::quadcontrol {

struct LoggedPose {
  std::int64_t sequence = 0;
  std::int64_t capture_us = 0;   ///< sensor clock (rgbd-streamer's capture stamp)
  std::int64_t received_us = 0;  ///< ground station: frame received
  std::int64_t pose_us = 0;      ///< ground station: SLAM result available to the controller
  bool tracking = false;
  Eigen::Isometry3d T_floor_cam = Eigen::Isometry3d::Identity();
  double yaw_deg = 0.0;
};

struct LoggedCommand {
  std::uint32_t seq = 0;     ///< control-link sequence number (matches the firmware's log)
  std::int64_t send_us = 0;  ///< when the request was started
  std::string state;         ///< flight state when computed
  PwmCommand pwm;
  std::int64_t pose_capture_us =
      -1;                     ///< capture stamp of the frame behind the pose used (-1: none yet)
  std::int64_t pose_us = -1;  ///< when that pose became available
};

class FlightLog {
 public:
  /// Creates `dir` (and parents) and the four files with their headers; nullptr + error on failure.
  static std::unique_ptr<FlightLog> open(const std::string& dir, std::string* error);
  ~FlightLog();
  FlightLog(const FlightLog&) = delete;
  FlightLog& operator=(const FlightLog&) = delete;

  void frame(std::int64_t sequence, std::int64_t capture_us, std::int64_t received_us,
             double link_latency_ms);
  void pose(const LoggedPose& pose);
  void command(const LoggedCommand& command);
  std::uint64_t write_errors() const;
  const std::string& dir() const { return dir_; }

 private:
  FlightLog(std::string dir, std::FILE* frames, std::FILE* poses, std::FILE* trajectory,
            std::FILE* commands);
  void write(std::FILE* f, const char* fmt, ...);

  std::string dir_;
  std::FILE* frames_;
  std::FILE* poses_;
  std::FILE* trajectory_;
  std::FILE* commands_;
  mutable std::mutex mutex_;
  std::uint64_t write_errors_ = 0;
};

}  // namespace rgbdquad::quadcontrol
