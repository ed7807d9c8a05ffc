// The craft's pose from SLAM: see craft_pose_tracker.hpp.
#include "core/craft_pose_tracker.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "core/geometry.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
PoseEstimator make_estimator(const CraftPoseTrackerOptions& options) {
  if (std::string e; !options.is_valid(&e)) throw std::invalid_argument(e);
  return PoseEstimator(options.estimator);
}
}  // namespace

bool CraftPoseTrackerOptions::is_valid(std::string* error) const {
  if (!floor.is_valid(error)) return false;
  if (!(mount_pitch_down_deg >= 0.0 && mount_pitch_down_deg < 90.0)) {
    return reject(error, "camera.mount_pitch_down_deg must be in [0, 90)");
  }
  if (floor_search_frames < 1) return reject(error, "floor_search_frames must be >= 1");
  if (!estimator.is_valid(error)) return false;
  return true;
}

CraftPose craft_pose_from(const Eigen::Isometry3d& T_floor_cam) {
  const Eigen::Vector3d t = T_floor_cam.translation();
  const Eigen::Vector3d forward = T_floor_cam.linear().col(2);
  return CraftPose{t.x(), t.y(), t.z(), std::atan2(forward.y(), forward.x()) * kDegPerRad};
}

Eigen::Quaterniond camera_attitude_ned(const ImuSample& sample, double mount_pitch_down_deg) {
  const Eigen::Matrix3d R_ned_body =
      (Eigen::AngleAxisd(sample.yaw_rad, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(sample.pitch_rad, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(sample.roll_rad, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  return Eigen::Quaterniond(R_ned_body * rotation_body_cam(mount_pitch_down_deg)).normalized();
}

bool CraftPoseTracker::on_imu(const ImuSample& sample) {
  // Each ATTITUDE message once, by when it was sampled: replies repeat it until the next arrives.
  const std::int64_t t_us = sample.attitude_t_us.value_or(sample.t_us);
  if (!last_attitude_t_us_ || t_us > *last_attitude_t_us_) {
    attitudes_.push(t_us, sample);
    last_attitude_t_us_ = t_us;
  }
  return estimator_.predict(sample);
}

std::optional<Eigen::Quaterniond> CraftPoseTracker::camera_attitude_at(
    std::int64_t capture_us, std::int64_t max_dt_us) const {
  const std::optional<std::int64_t> local_us = capture_clock_.peek(capture_us);
  if (!local_us) return std::nullopt;
  const auto sample = attitudes_.nearest(*local_us, max_dt_us);
  if (!sample) return std::nullopt;
  // A frame is usually handed to SLAM before the ATTITUDE sample after its capture has arrived
  // (25 Hz, then the serial link and the firmware's reply), so the nearest sample is up to ~40 ms
  // older than the image: at the 5-20 deg/s a craft rolls and pitches while it flies a waypoint,
  // 0.2-0.8 deg of tilt that the gravity prior would hold the pose to. Two consecutive samples
  // give the rate to carry the attitude to the capture (interpolated between them, or extrapolated
  // past the newest); a pair further apart than the match window (a lost message) is not used.
  if (const auto pair = attitudes_.pair_around(*local_us)) {
    const auto& [a, b] = *pair;
    const std::int64_t gap_us = b.first - a.first;
    if (gap_us > 0 && gap_us <= max_dt_us) {
      const double f = static_cast<double>(*local_us - a.first) / static_cast<double>(gap_us);
      const Eigen::Quaterniond q_a = camera_attitude_ned(a.second, options_.mount_pitch_down_deg);
      const Eigen::Quaterniond q_b = camera_attitude_ned(b.second, options_.mount_pitch_down_deg);
      const Eigen::AngleAxisd step(q_b * q_a.conjugate());  // NED-frame rotation from a to b
      return (Eigen::Quaterniond(Eigen::AngleAxisd(f * step.angle(), step.axis())) * q_a)
          .normalized();
    }
  }
  return camera_attitude_ned(sample->second, options_.mount_pitch_down_deg);
}

CraftPoseTracker::CraftPoseTracker(CraftPoseTrackerOptions options)
    : options_(std::move(options)), estimator_(make_estimator(options_)) {}

std::optional<FloorPlane> CraftPoseTracker::fit_floor(
    const std::vector<Eigen::Vector3d>& points_cam) const {
  return fit_floor_plane(points_cam, expected_up_in_camera(options_.mount_pitch_down_deg),
                         options_.floor);
}

bool CraftPoseTracker::search_floor(const SlamPoseInput& input,
                                    const std::optional<FloorPlane>& floor_candidate,
                                    CraftPoseUpdate& out) {
  if (T_floor_world_ || !input.tracking) return false;
  ++floor_attempts_;
  if (floor_candidate) {
    floor_ = floor_candidate;
    // World = first SLAM camera; T_floor_world = T_floor_cam * T_world_cam^-1.
    T_floor_world_ = floor_frame_from_plane(*floor_candidate) * input.T_world_cam.inverse();
    out.floor_found = true;
    return true;
  }
  if (floor_attempts_ < options_.floor_search_frames) return false;
  // No floor in view: gravity from the mount angle, height counted from the start (0 m).
  const FloorPlane assumed{expected_up_in_camera(options_.mount_pitch_down_deg), 0.0, 0, 0.0};
  T_floor_world_ = floor_frame_from_plane(assumed) * input.T_world_cam.inverse();
  floor_fallback_ = true;
  out.floor_fallback = true;
  return true;
}

CraftPoseUpdate CraftPoseTracker::update(std::int64_t now_us, const SlamPoseInput& input,
                                         const std::optional<FloorPlane>& floor_candidate) {
  CraftPoseUpdate out;
  const bool floor_set_now = search_floor(input, floor_candidate, out);
  if (!T_floor_world_ || floor_set_now) {
    // The floor frame belongs to the session it was found in (also when the very first result is
    // already tracking: without this the session never matched and no pose was ever used).
    session_ = input.session;
  } else if (input.session != session_ && input.tracking && last_T_floor_cam_) {
    // A new SLAM session (a new map; a resumed reconnect keeps the session number) has a new
    // world frame, its first camera. Re-anchor it on the last known camera pose: the craft
    // hovered in lost-hold meanwhile.
    T_floor_world_ = *last_T_floor_cam_ * input.T_world_cam.inverse();
    session_ = input.session;
    out.reanchored = true;
  }
  if (!T_floor_world_ || !input.tracking || input.session != session_) {
    // With the estimator the IMU bridges the gap (up to its max_prediction_ms), else lost at once.
    if (auto feed = estimate_feed(now_us)) {
      out.controller = *feed;
    } else {
      out.controller.sample = PoseSample{now_us, false, pose_.value_or(CraftPose{})};
    }
    return out;
  }
  out.T_floor_cam = *T_floor_world_ * input.T_world_cam;
  out.pose = craft_pose_from(out.T_floor_cam);
  out.tracking = true;
  if (pose_ && input.map_correction_count != map_correction_count_) {
    // A declared map correction: the estimator re-anchors by the jump (motion since the previous
    // pose, a few cm, is included), the controller sees the count change and does not reject it.
    const Eigen::Vector3d jump_m(out.pose.x_m - pose_->x_m, out.pose.y_m - pose_->y_m,
                                 out.pose.z_m - pose_->z_m);
    if (estimator_.shift_frame(jump_m)) out.map_correction_shift_m = jump_m;
  }
  map_correction_count_ = input.map_correction_count;
  pose_ = out.pose;
  last_T_floor_cam_ = out.T_floor_cam;
  // The estimator takes the pose at its capture instant (on the caller's clock) and carries it to
  // now.
  estimator_.fuse_pose(out.pose, capture_clock_.to_local(input.capture_us, input.received_us));
  if (auto feed = estimate_feed(now_us)) {
    out.controller = *feed;
  } else {
    out.controller.sample = PoseSample{now_us, true, out.pose, map_correction_count_};
  }
  return out;
}

std::optional<ControllerFeed> CraftPoseTracker::estimate_feed(std::int64_t now_us) {
  if (!options_.estimator.enabled) return std::nullopt;
  last_estimate_ = estimator_.estimate(now_us);
  if (!last_estimate_->imu_aided) return std::nullopt;
  const Eigen::Vector3d& v = last_estimate_->velocity_m_per_s;
  ++estimates_flown_;
  // Invalid (too old or too uncertain): tracking lost -> the controller's lost-hold / landing.
  return ControllerFeed{
      PoseSample{now_us, last_estimate_->valid, last_estimate_->pose, map_correction_count_},
      Velocity3{v.x(), v.y(), v.z()}, true};
}

}  // namespace rgbdquad::quadcontrol
