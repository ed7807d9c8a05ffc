// The hub of quad-control: joins the frame source, the SLAM link, the craft-pose tracker (SLAM
// results -> the craft's pose in the floor frame -> the controller's input; floor search, SLAM
// sessions, declared map corrections, IMU + pose estimator: core/craft_pose_tracker.hpp), the
// flight controller, the floor map and the firmware link, and exposes snapshots for the dashboard.
//
// Threads (all owned here, started by start(), joined in the destructor): the frame thread (source
// -> latest frame -> SLAM hand-over), the SLAM thread (inside SlamLink; its results go through the
// tracker into the controller, the logs and the map), and either the firmware link's I/O thread,
// which runs controller.update(now) just before each command it sends (every firmware.period_ms, or
// with firmware.send_on_pose on each fresh tracked pose, rate-limited, plus keep-alives), or, with
// no firmware, the control thread (controller.update(now) every control_period_ms, for the
// dashboard). The SLAM link is created on the first frame (it needs the intrinsics). Shared state
// is guarded by one mutex; everything below is only touched under it.
//
// Time is a parameter: the clock is read at the edges only (the control thread's tick, the SLAM
// callback, the firmware link, the dashboard's HTTP handler) and passed in as `now_us`. The hub
// itself holds the threads, the lock, the routing between the parts and the flight log and MCAP
// recorder calls; the state lives in parts of its own, each pure and tested alone: the tracker,
// the controller, the map (StationMap: FloorMap, revision, renderings, depth sub-sampling), the
// newest frame's images (FrameImages), the stream figures (StreamStats) and the track
// (TrajectoryTrail). Unstarted, the station is driven by calling the threads' steps
// (tests/ground_station_test.cpp).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "app/dashboard_backend.hpp"
#include "app/firmware_link.hpp"
#include "app/flight_log.hpp"
#include "app/frame_images.hpp"
#include "app/frame_source.hpp"
#include "app/slam_link.hpp"
#include "app/slam_server_client.hpp"
#include "app/station_map.hpp"
#include "core/craft_pose_tracker.hpp"
#include "core/flight_controller.hpp"
#include "core/stream_stats.hpp"
#include "core/timestamp_buffer.hpp"
#include "core/trajectory_trail.hpp"
#include "map/floor_map.hpp"
#include "map/floor_plane.hpp"
#include "record/flight_recorder.hpp"

namespace rgbdquad::quadcontrol {

struct GroundStationOptions {
  ControlConfig controller;
  FloorPlaneOptions floor;
  FloorMapOptions map;
  double mount_pitch_down_deg = 30.0;  ///< Kinect tilt on the craft (thesis: mounted at an angle)
  /// Hand the camera's IMU attitude at capture to SLAM (either link), which then predicts each
  /// frame's rotation from the attitude change instead of the constant-velocity model. Both SLAM
  /// links carry it (the SLAM-server link in RgbdFrame.attitude). HIL scenarios 1, 2, 4 and 5 flown
  /// with it and without: docs/control.md.
  bool imu_rotation_prior = true;
  int floor_search_frames = 30;  ///< ~1 s at 30 Hz to find the floor, then fall back
  int floor_pixel_step = 4;      ///< depth sub-sampling for the RANSAC (19200 points)
  int map_pixel_step = 8;        ///< depth sub-sampling for the map (4800 points/frame)
  double max_depth_m = 4.0;      ///< Kinect depth beyond ~4 m is too noisy for a map
  int control_period_ms = 20;    ///< 50 Hz, the firmware command rate
  std::size_t trajectory_max_points = 5000;
  std::int64_t imu_match_window_us = 20000;  ///< TUM's association rule: nearest within 20 ms
  /// The attitude handed to SLAM with a frame (`imu_rotation_prior`): the sample nearest to the
  /// capture within 60 ms. The frame reaches SLAM ~2 ms after capture, before the ATTITUDE sampled
  /// after it has come back, so the newest one is up to an ATTITUDE period (40 ms at the APM's
  /// 25 Hz stream rate) plus a reply's way back (up to 20 ms on the 50 Hz command grid) old.
  std::int64_t attitude_match_window_us = 60000;
  std::string slam_mode =
      "server";  ///< "server": slam-server over the SLAM link; "in-process": local-map SLAM here
  SlamServerOptions slam_server;
  /// Scheduling of the real-time path (frame, SLAM link and firmware link threads; config key
  /// "realtime"): SCHED_RR 10 by default, nice -10 where refused, each thread logs what it got.
  slam::ThreadPriorityOptions realtime;
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
  /// The craft-pose tracker's part (floor search, mount angle, estimator).
  CraftPoseTrackerOptions tracker() const;
};

/// What /api/state shows: copied under the hub's lock (and from the links' own thread-safe stats),
/// serialised by to_json() after the lock is released.
struct StationSnapshot {
  std::int64_t taken_us = 0;  ///< `now_us` it was taken at ("connected": a reply within 1 s)
  ControllerStatus controller;
  std::optional<CraftPose> pose;  ///< the tracker's newest tracked pose
  std::uint32_t map_correction_count = 0;
  StickCommand stick;
  PwmCommand pwm;
  std::string source;  ///< the frame source's description
  std::int64_t frames = 0;
  double fps = 0.0;
  std::int64_t sequence = -1;  ///< of the newest frame; -1 before the first
  double stream_latency_ms = 0.0;
  std::string source_error;
  std::string slam_link_name;
  std::string slam_state = "waiting";  ///< of the newest SLAM result
  std::size_t slam_inliers = 0;
  SlamStats slam_stats;
  SlamLinkStatus slam_link;
  std::optional<FirmwareLinkStats> firmware;  ///< nullopt: no firmware link
  std::optional<double> imu_match_dt_ms;
  bool estimator_enabled = false;
  std::optional<StateEstimate> estimate;  ///< the newest the controller was offered
  EstimatorStats estimator_stats;
  std::uint64_t estimates_flown = 0;
  std::optional<RecorderStats> recording;  ///< nullopt: not recording
  std::optional<FloorPlane> floor;
  bool floor_fallback = false;
  double map_origin_x_m = 0.0, map_origin_y_m = 0.0, map_resolution_m = 0.0;
  int map_width_cells = 0, map_height_cells = 0;
  std::int64_t map_revision = 0;
  std::size_t cloud_points = 0;
  std::vector<std::array<double, 2>>
      trajectory;  ///< x, y (m); decimated to every n-th point, n = size / 500
};

/// The dashboard's /api/state body (docs/control.md, "Dashboard and API").
nlohmann::json to_json(const StationSnapshot& snapshot);

class GroundStation : public DashboardBackend {
 public:
  /// Sets up the station; start() starts its threads. `firmware` may be null options (no craft:
  /// commands are computed, not sent; with options the firmware link starts its own thread here);
  /// `log` may be null (no flight recorder).
  GroundStation(GroundStationOptions options, std::unique_ptr<FrameSource> source,
                std::optional<FirmwareLinkOptions> firmware, ControlSpec spec,
                rgbd_control::Key key, std::unique_ptr<FlightLog> log = nullptr,
                std::unique_ptr<FlightRecorder> recorder = nullptr);
  ~GroundStation();
  GroundStation(const GroundStation&) = delete;
  GroundStation& operator=(const GroundStation&) = delete;

  /// Starts the frame thread, and the control thread when there is no firmware link. Once only.
  void start();

  // The steps the threads run, public so that a test can drive the station without threads
  // (thread-safe: each takes the lock).
  /// One frame from the source: counted, logged, recorded, its IMU attitude set (the frame thread,
  /// before handing it to SLAM).
  void on_frame(CameraFrame& frame);
  /// Takes a SLAM result, arrived at `now_us`, through the tracker into the controller, the logs
  /// and the map; true when it gave the controller a fresh tracked pose (then the firmware link is
  /// told, outside the lock).
  bool apply_slam_result(std::int64_t now_us, const SlamResult& result, const CameraFrame& frame);
  /// The control thread's tick without a craft: the controller at `now_us`, nothing sent.
  void control_step(std::int64_t now_us);
  /// The firmware link's command provider: runs the controller at `now_us` on the newest pose;
  /// nullopt while the controller hands the craft over to its failsafe (nothing is sent).
  std::optional<PwmCommand> command_at(std::int64_t now_us, std::uint32_t seq);
  /// A firmware reply received at `received_us` (IMU for the tracker, matched to frames).
  void on_reply(std::int64_t received_us, const rgbd_control::Reply& reply);

  // Dashboard API (thread-safe; dashboard_backend.hpp). `now_us`: monotonic_now_us() read by
  // the caller.
  nlohmann::json state_json(std::int64_t now_us) override;
  std::optional<std::string> rgb_jpeg() override;
  std::optional<std::string> depth_png() override;
  std::string map_png() override;
  nlohmann::json cloud_json(std::size_t max_points) override;
  std::string map_ply() override;
  std::string command(std::int64_t now_us, OperatorCommand command) override;
  std::string waypoint(std::int64_t now_us, double x_m, double y_m) override;
  std::string manual(std::int64_t now_us, double forward_m, double left_m, double up_m,
                     double yaw_ccw_deg) override;
  std::string manoeuvre(std::int64_t now_us, const ManoeuvreRequest& request) override;

 private:
  void frame_loop();
  void control_loop();
  void on_slam(const SlamResult& result, const CameraFrame& frame);
  /// on_frame() with mutex_ held.
  void take_frame(CameraFrame& frame);
  /// Feeds the controller the estimator's state at `now_us` (caller holds mutex_) when the
  /// estimator is on and has fresh IMU input; else nothing (the raw poses drive the controller).
  void feed_estimate(std::int64_t now_us);
  /// MCAP recorder hooks (caller holds mutex_; recorder_ set): the controller's status, and the
  /// command when one is sent; a SLAM result as a PoseRecord.
  void record_command(std::int64_t now_us, std::uint32_t seq, bool sent);
  void record_pose(const SlamResult& result, const CameraFrame& frame, std::int64_t now_us,
                   bool tracking, const Eigen::Isometry3d& T_floor_cam);
  /// How the APM reads the sticks (dead zones from the controller config).
  ApmStickInput apm_input() const;

  GroundStationOptions options_;
  ControlSpec spec_;
  std::unique_ptr<FrameSource> source_;
  std::atomic<bool> stop_{false};

  slam::PriorityInheritanceMutex mutex_;  ///< taken by real-time threads and the dashboard
  FlightController controller_;
  /// SLAM results -> the craft's pose in the floor frame and the controller's input (floor search,
  /// SLAM sessions, declared map corrections, the IMU + pose estimator).
  CraftPoseTracker tracker_;
  StationMap map_;
  FrameImages images_;  ///< the newest frame and its dashboard images
  StreamStats stream_;
  std::optional<SlamResult> last_slam_;
  std::int64_t pose_capture_us_ = -1;  ///< capture stamp of the frame behind the pose (flight log)
  std::int64_t pose_us_ = -1;          ///< when the tracker's pose became available
  TrajectoryTrail trajectory_;
  StickCommand last_stick_;
  PwmCommand last_pwm_;
  TimestampBuffer<rgbd_control::Reply> imu_replies_{256};
  std::optional<double> imu_match_dt_ms_;

  std::unique_ptr<SlamLink> slam_;  ///< set once by the frame thread, then slam_ready_
  std::atomic<bool> slam_ready_{false};
  std::unique_ptr<FlightLog> log_;  ///< null: no flight recorder
  std::unique_ptr<FlightRecorder>
      recorder_;  ///< null: not recording MCAP (never blocks: bounded queue)
  std::unique_ptr<FirmwareLink> firmware_;
  std::thread frame_thread_;
  std::thread control_thread_;
};

}  // namespace rgbdquad::quadcontrol
