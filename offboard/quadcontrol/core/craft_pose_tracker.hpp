// The craft's pose from SLAM: turns SLAM's camera poses (T_world_cam, world = the first camera of
// the SLAM session) into the craft's pose in the floor frame (z up = height above the floor, x/y on
// the floor; geometry.hpp) and decides what the flight controller flies on. Not to be confused
// with SLAM's own tracker (offboard/slam): this one works on SLAM's output.
//
// It owns, per SLAM result (update()):
//  * the floor search: the first `floor_search_frames` tracked frames are searched for the floor
//    (FloorPlane RANSAC, run by the caller through fit_floor()); the first plane found fixes
//    T_floor_world. Without a floor in view by then, gravity is taken from the mount angle and the
//    height counted from the start (0 m): the fallback.
//  * T_floor_world, which belongs to one SLAM session. A new session (slam-server restarted or its
//    grace period passed: a new map, its world frame is its first camera) is re-anchored on the
//    last known T_floor_cam: the craft hovered in lost-hold meanwhile, so its pose is continuous.
//  * declared map corrections: when SLAM's map_correction_count changes, the jump of the pose
//    since the previous one shifts the estimator's frame (PoseEstimator::shift_frame) and the
//    count goes to the controller, which flies a bounded declared correction instead of rejecting
//    it as a jump. A jump without a count change is passed on unchanged (the controller's jump
//    gate rejects it).
//  * the pose estimator (IMU + delayed poses, core/pose_estimator.hpp) and the capture clock: the
//    controller flies on the estimate while it is enabled and IMU-aided, else on the raw pose.
//
// Pure: no clock, no I/O, no threads; times are microseconds of the caller's monotonic clock,
// passed in. Not thread-safe: the owner (quad-control's GroundStation) guards it with its lock;
// fit_floor() only reads the options, which never change, so it may run outside that lock.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/estimator_options.hpp"
#include "core/flight_controller.hpp"
#include "core/pose_estimator.hpp"
#include "core/timestamp_buffer.hpp"
#include "map/floor_plane.hpp"

namespace rgbdquad::quadcontrol {

struct CraftPoseTrackerOptions {
  FloorPlaneOptions floor;
  double mount_pitch_down_deg = 30.0;  ///< Kinect tilt on the craft (thesis: mounted at an angle)
  int floor_search_frames = 30;        ///< ~1 s at 30 Hz to find the floor, then fall back
  EstimatorOptions estimator;          ///< the controller's ("controller": {"estimator": ...})
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

/// One SLAM result as the tracker needs it (quad-control's SlamResult, app/slam_link.hpp, converted
/// by the hub).
struct SlamPoseInput {
  bool tracking = false;                                          ///< false: pose is meaningless
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< world = session's 1st camera
  std::uint64_t session = 0;  ///< SLAM session (a new number = a new map, a new world frame)
  std::uint32_t map_correction_count = 0;  ///< SLAM's declared world-frame corrections so far
  std::int64_t capture_us = 0;   ///< camera capture stamp of the frame (the craft's clock)
  std::int64_t received_us = 0;  ///< when the frame arrived (caller's clock)
};

/// What FlightController::on_pose() gets: the sample and, from the estimator, a velocity.
struct ControllerFeed {
  PoseSample sample;
  std::optional<Velocity3> velocity_m_per_s;  ///< set when from_estimator
  bool from_estimator = false;                ///< false: the raw SLAM pose (or lost)
};

/// The outcome of one SLAM result.
struct CraftPoseUpdate {
  /// Always to be handed to FlightController::on_pose(), tracking or not (a lost sample starts
  /// the controller's lost-hold unless the estimator bridges the gap).
  ControllerFeed controller;
  /// A fresh pose in the floor frame (the SLAM result was tracking, the floor frame is known and
  /// belongs to the result's session); pose and T_floor_cam are set only then.
  bool tracking = false;
  CraftPose pose;
  Eigen::Isometry3d T_floor_cam = Eigen::Isometry3d::Identity();  ///< maps camera -> floor points
  // Events of this result.
  bool floor_found = false;     ///< the floor plane fixed the floor frame
  bool floor_fallback = false;  ///< the search gave up: floor frame from the mount angle
  bool reanchored = false;      ///< a new SLAM session was anchored on the last T_floor_cam
  /// A declared map correction: the jump (new pose - previous pose, floor frame, m) the
  /// estimator's frame was shifted by (it was refused when the estimator had no pose yet).
  std::optional<Eigen::Vector3d> map_correction_shift_m;
};

/// The craft's heading and position from T_floor_cam: position = camera centre, heading = the
/// optical axis (camera +z) projected on the floor, degrees counter-clockwise from floor +x.
CraftPose craft_pose_from(const Eigen::Isometry3d& T_floor_cam);

/// The camera's attitude in NED from one APM attitude (ZYX Euler) and the Kinect's mount (looking
/// along body x, pitched down by mount_pitch_down_deg; camera x right, y down, z forward), i.e.
/// R_ned_cam = R_ned_body * R_body_cam.
Eigen::Quaterniond camera_attitude_ned(const ImuSample& sample, double mount_pitch_down_deg);

class CraftPoseTracker {
 public:
  /// `options` must be valid (is_valid()); throws std::invalid_argument otherwise.
  explicit CraftPoseTracker(CraftPoseTrackerOptions options);

  /// True while the floor frame is unknown: the caller should run fit_floor() on the depth of a
  /// tracking result and pass its answer to update().
  bool searching_floor() const { return !T_floor_world_.has_value(); }
  /// RANSAC for the floor plane in depth points of the camera frame (m); nullopt when none is
  /// visible enough. Reads only the options: callable outside the owner's lock.
  std::optional<FloorPlane> fit_floor(const std::vector<Eigen::Vector3d>& points_cam) const;

  /// Takes one SLAM result at `now_us`. `floor_candidate`: fit_floor()'s answer on this frame's
  /// depth while searching_floor() (ignored otherwise). The caller hands result.controller to
  /// FlightController::on_pose().
  CraftPoseUpdate update(std::int64_t now_us, const SlamPoseInput& input,
                         const std::optional<FloorPlane>& floor_candidate);

  /// An IMU sample of the APM (PoseEstimator::predict); false when dropped.
  bool on_imu(const ImuSample& sample);
  /// The camera's NED attitude at a frame's capture stamp (craft clock), through
  /// camera_attitude_ned(): interpolated between the two ATTITUDE samples around it on this clock,
  /// or extrapolated from the newest two when it is newer than both, when those two are at most
  /// `max_dt_us` apart; otherwise the sample nearest to it. nullopt before the first tracked frame
  /// has set the clock offset, or with no sample within `max_dt_us`. For the SLAM tracker's
  /// rotation prediction and gravity prior (slam::RgbdFrame::q_nav_cam).
  std::optional<Eigen::Quaterniond> camera_attitude_at(std::int64_t capture_us,
                                                       std::int64_t max_dt_us) const;
  /// The estimator's state at `now_us` for the controller, when the estimator is enabled and has
  /// fresh IMU input (an invalid estimate comes as a lost sample: lost-hold); nullopt otherwise
  /// (the raw poses of update() drive the controller then). Records last_estimate().
  std::optional<ControllerFeed> estimate_feed(std::int64_t now_us);

  /// The newest tracked craft pose (floor frame); nullopt before the first.
  const std::optional<CraftPose>& pose() const { return pose_; }
  /// SLAM's map-correction count of the newest tracked pose (what the controller was told).
  std::uint32_t map_correction_count() const { return map_correction_count_; }
  /// The floor plane found (camera frame of the frame it was found in); nullopt before, or when the
  /// floor frame came from the fallback.
  const std::optional<FloorPlane>& floor() const { return floor_; }
  bool floor_fallback() const { return floor_fallback_; }
  const std::optional<Eigen::Isometry3d>& T_floor_world() const { return T_floor_world_; }
  /// The SLAM session T_floor_world belongs to.
  std::uint64_t session() const { return session_; }
  const PoseEstimator& estimator() const { return estimator_; }
  /// The estimate of the newest estimate_feed() with the estimator enabled.
  const std::optional<StateEstimate>& last_estimate() const { return last_estimate_; }
  /// Controller steps fed from the estimator.
  std::uint64_t estimates_flown() const { return estimates_flown_; }
  const CraftPoseTrackerOptions& options() const { return options_; }

 private:
  /// Sets the floor frame on a tracking result while searching; true when it was set now.
  bool search_floor(const SlamPoseInput& input, const std::optional<FloorPlane>& floor_candidate,
                    CraftPoseUpdate& out);

  CraftPoseTrackerOptions options_;
  std::optional<Eigen::Isometry3d> T_floor_world_;
  std::optional<Eigen::Isometry3d> last_T_floor_cam_;  ///< re-anchors a new SLAM session
  std::uint64_t session_ = 0;                          ///< the session T_floor_world_ belongs to
  std::optional<FloorPlane> floor_;
  bool floor_fallback_ = false;
  int floor_attempts_ = 0;  ///< tracking results seen while searching the floor
  std::optional<CraftPose> pose_;
  std::uint32_t map_correction_count_ = 0;
  PoseEstimator estimator_;
  CaptureClock capture_clock_;  ///< the craft's capture stamps -> the caller's clock
  /// Recent ATTITUDE samples by when they were sampled, caller's clock: 64 = 2.6 s at the APM's
  /// 25 Hz stream rate, far longer than a frame's transit to the ground station.
  TimestampBuffer<ImuSample> attitudes_{64};
  std::optional<std::int64_t> last_attitude_t_us_;
  std::optional<StateEstimate> last_estimate_;
  std::uint64_t estimates_flown_ = 0;
};

}  // namespace rgbdquad::quadcontrol
