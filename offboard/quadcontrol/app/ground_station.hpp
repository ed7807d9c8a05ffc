// The hub of quad-control: joins the frame source, the SLAM link, the flight controller, the floor
// map and the firmware link, and exposes snapshots for the dashboard.
//
// Threads (all owned here, joined in the destructor): the frame thread (source -> latest frame ->
// SLAM hand-over), the SLAM thread (inside SlamLink; its results update pose, floor frame and map),
// and either the firmware link's I/O thread, which runs controller.update(now) just before each
// command it sends (every firmware.period_ms, or with firmware.send_on_pose on each fresh tracked
// pose, rate-limited, plus keep-alives), or, with no firmware, the
// control thread (controller.update(now) every control_period_ms, for the dashboard). The SLAM link is created on the first frame (it needs the intrinsics). Shared state is guarded by one mutex; the controller is only touched
// under it. This is the only place that reads the clock and passes it into the logic.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/dashboard_backend.hpp"
#include "app/firmware_link.hpp"
#include "app/flight_log.hpp"
#include "app/frame_source.hpp"
#include "app/slam_link.hpp"
#include "app/slam_server_client.hpp"
#include "core/flight_controller.hpp"
#include "core/pose_estimator.hpp"
#include "core/timestamp_buffer.hpp"
#include "map/floor_map.hpp"
#include "map/floor_plane.hpp"
#include "record/flight_recorder.hpp"

namespace rgbdquad::quadcontrol {

struct GroundStationOptions {
  ControlConfig controller;
  FloorPlaneOptions floor;
  FloorMapOptions map;
  double mount_pitch_down_deg = 30.0;  ///< Kinect tilt on the craft (thesis: mounted at an angle)
  int floor_search_frames = 30;        ///< ~1 s at 30 Hz to find the floor, then fall back
  int floor_pixel_step = 4;            ///< depth sub-sampling for the RANSAC (19200 points)
  int map_pixel_step = 8;              ///< depth sub-sampling for the map (4800 points/frame)
  double max_depth_m = 4.0;            ///< Kinect depth beyond ~4 m is too noisy for a map
  int control_period_ms = 20;          ///< 50 Hz, the firmware command rate
  std::size_t trajectory_max_points = 5000;
  std::int64_t imu_match_window_us = 20000;  ///< TUM's association rule: nearest within 20 ms
  std::string slam_mode = "server";  ///< "server": slam-server over the SLAM link; "in-process": local-map SLAM here
  SlamServerOptions slam_server;
  /// Scheduling of the real-time path (frame, SLAM link and firmware link threads; config key
  /// "realtime"): SCHED_RR 10 by default, nice -10 where refused, each thread logs what it got.
  slam::ThreadPriorityOptions realtime;
  std::string validate() const;
};

class GroundStation : public DashboardBackend {
 public:
  /// Starts every thread. `firmware` may be null options (no craft: commands are computed, not sent);
  /// `log` may be null (no flight recorder).
  GroundStation(GroundStationOptions options, std::unique_ptr<FrameSource> source,
                std::optional<FirmwareLinkOptions> firmware, ControlSpec spec, rgbd_control::Key key,
                std::unique_ptr<FlightLog> log = nullptr, std::unique_ptr<FlightRecorder> recorder = nullptr);
  ~GroundStation();
  GroundStation(const GroundStation&) = delete;
  GroundStation& operator=(const GroundStation&) = delete;

  // Dashboard API (thread-safe; dashboard_backend.hpp).
  nlohmann::json state_json() override;
  std::optional<std::string> rgb_jpeg() override;
  std::optional<std::string> depth_png() override;
  std::string map_png() override;
  nlohmann::json cloud_json(std::size_t max_points) override;
  std::string map_ply() override;
  std::string command(OperatorCommand command) override;
  std::string waypoint(double x_m, double y_m) override;
  std::string manual(double forward_m, double left_m, double up_m, double yaw_ccw_deg) override;

 private:
  void frame_loop();
  void control_loop();
  /// The firmware link's command provider: runs the controller at `now_us` on the newest pose;
  /// nullopt while the controller hands the craft over to its failsafe (nothing is sent).
  std::optional<PwmCommand> command_at(std::int64_t now_us, std::uint32_t seq);
  void on_slam(const SlamResult& result, const CameraFrame& frame);
  /// Takes a SLAM result into pose, floor frame and map; true when it gave the controller a fresh
  /// tracked pose (then the firmware link is told, outside the lock).
  bool apply_slam_result(const SlamResult& result, const CameraFrame& frame);
  void on_reply(std::int64_t received_us, const rgbd_control::Reply& reply);
  /// Feeds the controller the estimator's state at `now_us` (caller holds mutex_); false when the
  /// estimator is off or has no fresh IMU input (the raw poses drive the controller then).
  bool feed_estimate(std::int64_t now_us);
  /// MCAP recorder hooks (caller holds mutex_; recorder_ set): the controller's status, and the
  /// command when one is sent; a SLAM result as a PoseRecord.
  void record_command(std::int64_t now_us, std::uint32_t seq, bool sent);
  void record_pose(const SlamResult& result, const CameraFrame& frame, std::int64_t now_us, bool tracking,
                   const Eigen::Isometry3d& T_floor_cam);
  std::vector<Eigen::Vector3d> depth_points(const CameraFrame& frame, int step) const;
  /// How the APM reads the sticks (dead zones from the controller config).
  ApmStickInput apm_input() const;
  /// Drops the encoded RGB/depth images when latest_frame_ changed. Caller holds mutex_ and has a frame.
  void invalidate_image_caches_if_new_frame();

  GroundStationOptions options_;
  ControlSpec spec_;
  std::unique_ptr<FrameSource> source_;
  std::atomic<bool> stop_{false};

  slam::PriorityInheritanceMutex mutex_;  ///< taken by real-time threads and the dashboard
  FlightController controller_;
  FloorMap map_;
  std::optional<CameraFrame> latest_frame_;
  std::optional<std::string> rgb_jpeg_cache_, depth_png_cache_;
  std::int64_t cache_sequence_ = -1;
  std::int64_t frames_ = 0;
  double fps_ = 0.0;
  std::int64_t last_frame_us_ = 0;
  double stream_latency_ms_ = 0.0;
  std::string source_error_;
  std::optional<SlamResult> last_slam_;
  std::optional<CraftPose> pose_;
  std::uint32_t map_correction_count_ = 0;  ///< of the newest result (handed to the controller)
  std::int64_t pose_capture_us_ = -1;  ///< capture stamp of the frame behind pose_ (flight log)
  std::int64_t pose_us_ = -1;          ///< when pose_ became available
  std::optional<Eigen::Isometry3d> T_floor_world_;
  std::optional<Eigen::Isometry3d> last_T_floor_cam_;  ///< re-anchors a new SLAM session
  std::uint64_t slam_session_ = 0;                      ///< session T_floor_world_ belongs to
  std::optional<FloorPlane> floor_;
  bool floor_fallback_ = false;
  int floor_attempts_ = 0;
  std::int64_t map_revision_ = 0;
  std::vector<std::array<double, 2>> trajectory_;
  StickCommand last_stick_;
  PwmCommand last_pwm_;
  TimestampBuffer<rgbd_control::Reply> imu_replies_{256};
  std::optional<double> imu_match_dt_ms_;
  /// IMU + delayed pose fusion (controller.estimator): the controller flies on its estimate now
  /// while the IMU telemetry is fresh, else on the raw poses as before.
  PoseEstimator estimator_{options_.controller.estimator};
  CaptureClock capture_clock_;          ///< the craft's capture stamps -> this clock
  std::optional<StateEstimate> last_estimate_;
  std::uint64_t estimates_flown_ = 0;   ///< controller steps fed from the estimator

  std::unique_ptr<SlamLink> slam_;  ///< set once by the frame thread, then slam_ready_
  std::atomic<bool> slam_ready_{false};
  std::unique_ptr<FlightLog> log_;  ///< null: no flight recorder
  std::unique_ptr<FlightRecorder> recorder_;  ///< null: not recording MCAP (never blocks: bounded queue)
  std::unique_ptr<FirmwareLink> firmware_;
  std::thread frame_thread_;
  std::thread control_thread_;
};

}  // namespace rgbdquad::quadcontrol
