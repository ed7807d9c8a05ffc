// SLAM-link session: RgbdFrame -> exactly one PoseUpdate.
#include "slam_link_session.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "rgbdquad/protocol/codec.hpp"

namespace rgbdquad::slamlink {

namespace proto = rgbdquad::protocol;

namespace {
// A rotation matrix gives |q| = 1 to ~1e-15; 1e-3 means the matrix is not a rotation at all
// (scaled or sheared), which re-normalising would hide.
constexpr double kMaxQuaternionNormError = 1e-3;

proto::TrackingState to_wire(slam::TrackingState s) {
  switch (s) {
    case slam::TrackingState::kInitialising:
      return proto::TrackingState::kInitializing;
    case slam::TrackingState::kTracking:
      return proto::TrackingState::kTracking;
    case slam::TrackingState::kLost:
      return proto::TrackingState::kLost;
  }
  return proto::TrackingState::kLost;
}
// The conversion slam-server used before pose_to_wire, kept to recognise the poses it could not
// send.
proto::Pose3 raw_pose(const Eigen::Isometry3d& T) {
  proto::Pose3 p;
  const Eigen::Quaterniond q(T.rotation());
  p.t_m = {T.translation().x(), T.translation().y(), T.translation().z()};
  p.q_xyzw = {q.x(), q.y(), q.z(), q.w()};
  return p;
}
}  // namespace

std::optional<proto::Pose3> pose_to_wire(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return std::nullopt;
  Eigen::Quaterniond q(T.linear());
  const double norm = q.norm();
  if (!(std::fabs(norm - 1.0) <= kMaxQuaternionNormError)) return std::nullopt;
  q.coeffs() /= norm;
  proto::Pose3 p;
  p.t_m = {T.translation().x(), T.translation().y(), T.translation().z()};
  p.q_xyzw = {q.x(), q.y(), q.z(), q.w()};
  for (double& c : p.q_xyzw) c = std::clamp(c, -1.0, 1.0);
  const proto::FieldRange range = proto::field_range::kPose3TM;
  for (double t : p.t_m)
    if (!(t >= range.lo && t <= range.hi)) return std::nullopt;
  return p;
}

SlamLinkSession::SlamLinkSession(slam::PipelineOptions options, SessionMapFiles map_files,
                                 PipelineFactory factory)
    : options_(std::move(options)), map_files_(std::move(map_files)), factory_(std::move(factory)) {
  // Tracking answers each frame on the caller's thread; local mapping runs on its own thread.
  options_.mode = slam::PipelineMode::kLive;
}

std::optional<slam::RgbdFrame> SlamLinkSession::to_frame(const proto::RgbdFrame& m,
                                                         std::string* error) {
  const auto& rh = m.rgb.header;
  const auto& dh = m.depth.header;
  if (rh.encoding != proto::Encoding::kRaw || dh.encoding != proto::Encoding::kRaw) {
    if (error) *error = "slam-link: only RAW image encodings are supported by slam-server";
    return std::nullopt;
  }
  if (rh.pixel_format != proto::PixelFormat::kRgb8 ||
      dh.pixel_format != proto::PixelFormat::kDepth16 || rh.width != dh.width ||
      rh.height != dh.height || rh.width == 0 || rh.height == 0) {
    if (error) *error = "slam-link: need RGB8 and DEPTH16 images of the same non-zero size";
    return std::nullopt;
  }
  const std::size_t n = static_cast<std::size_t>(rh.width) * rh.height;
  if (m.rgb.payload.size() != 3 * n || m.depth.payload.size() != 2 * n) {
    if (error) *error = "slam-link: payload size does not match width x height";
    return std::nullopt;
  }
  slam::RgbdFrame f;
  f.index = static_cast<std::int64_t>(frames_);
  f.stamp_s = slam::seconds_from_us(static_cast<std::int64_t>(dh.capture_timestamp_us));
  if (m.attitude.valid) {  // the codec has checked it is a unit quaternion
    const auto& q = m.attitude.q_xyzw;
    f.q_nav_cam = Eigen::Quaterniond(q[3], q[0], q[1], q[2]);
  }
  // The sample belongs to the colour image: the gate judges it at the colour stamp.
  std::optional<slam::AccelSample> accel;
  if (m.accel.valid)
    accel = slam::AccelSample{
        slam::seconds_from_us(static_cast<std::int64_t>(m.accel.capture_timestamp_us)),
        Eigen::Vector3d(m.accel.f_mps2[0], m.accel.f_mps2[1], m.accel.f_mps2[2])};
  accel_gate_.attach(slam::seconds_from_us(static_cast<std::int64_t>(rh.capture_timestamp_us)),
                     accel, &f);
  cv::Mat rgb(rh.height, rh.width, CV_8UC3, const_cast<std::uint8_t*>(m.rgb.payload.data()));
  cv::cvtColor(rgb, f.rgb, cv::COLOR_RGB2BGR);  // copies
  f.depth.create(dh.height, dh.width, CV_16UC1);
  const std::uint8_t* src = m.depth.payload.data();
  for (std::size_t i = 0; i < n; ++i)  // little-endian on the wire
    f.depth.ptr<std::uint16_t>()[i] =
        static_cast<std::uint16_t>(src[2 * i] | (src[2 * i + 1] << 8));
  return f;
}

proto::PoseUpdate SlamLinkSession::lost_update(const proto::RgbdFrame& frame, std::string reason,
                                               std::string* error) {
  ++faulted_;
  if (error) *error = std::move(reason);
  proto::PoseUpdate u;
  u.pair_sequence = frame.pair_sequence;
  u.timestamp_us = frame.rgb.header.capture_timestamp_us;
  u.tracking_state = proto::TrackingState::kLost;
  u.T_world_cam = last_good_;
  u.T_prev_cur = proto::Pose3{};  // identity: motion unknown
  u.is_keyframe = false;
  u.inlier_count = 0;
  u.map_correction_count = map_corrections_;  // a fault is not a map correction
  return u;
}

namespace {

slam::Intrinsics intrinsics_of(const proto::RgbdFrame& frame) {
  slam::Intrinsics k;
  k.fx_px = frame.intrinsics.fx_px;
  k.fy_px = frame.intrinsics.fy_px;
  k.cx_px = frame.intrinsics.cx_px;
  k.cy_px = frame.intrinsics.cy_px;
  k.distortion = frame.intrinsics.distortion;
  k.depth_units_per_m = frame.depth_scale_units_per_m;
  return k;
}

bool same_camera(const slam::Intrinsics& a, const slam::Intrinsics& b) {
  return a.fx_px == b.fx_px && a.fy_px == b.fy_px && a.cx_px == b.cx_px && a.cy_px == b.cy_px &&
         a.distortion == b.distortion && a.depth_units_per_m == b.depth_units_per_m;
}

std::string describe(const slam::Intrinsics& k) {
  std::ostringstream m;
  m << "fx " << k.fx_px << " fy " << k.fy_px << " cx " << k.cx_px << " cy " << k.cy_px
    << " px, depth " << k.depth_units_per_m << " units/m";
  return m.str();
}

}  // namespace

std::string SlamLinkSession::start_pipeline(const slam::Intrinsics& k) {
  std::string err;
  slam::PipelineOptions options = options_;
  options.checkpoint_path = map_files_.checkpoint_path;
  bool tables_dir_ok = false;
  if (!map_files_.tables_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(map_files_.tables_dir, ec);
    if (ec)
      tables_error_ = "cannot create " + map_files_.tables_dir + ": " + ec.message();
    else
      tables_dir_ok = true;
  }
  // Beside the map's frames.csv: what a replay of the recorded frames needs to give the same
  // poses (flight_recording.replay --lock-schedule).
  if (tables_dir_ok)
    options.lock_schedule_record_path =
        (std::filesystem::path(map_files_.tables_dir) / kLockScheduleFile).string();
  pipeline_ = factory_(options, k, &err);
  if (!pipeline_) return "slam-link: cannot start the pipeline: " + err;
  intrinsics_ = k;
  if (map_files_.resume_from_checkpoint) {
    if (!pipeline_->load_map(map_files_.checkpoint_path, &err))
      resume_error_ = "slam-link: the map's checkpoint cannot be resumed (" + err +
                      "); its world frame is lost: start a new map";
  } else if (!map_files_.load_path.empty() && !pipeline_->load_map(map_files_.load_path, &err)) {
    // The flight goes on in a new map: say so on every frame's first answer, never silently.
    map_load_error_ = "slam-link: map not loaded, starting a new map: " + err;
  }
  if (tables_dir_ok && !pipeline_->start_tables(map_files_.tables_dir, &err)) tables_error_ = err;
  return "";
}

proto::PoseUpdate SlamLinkSession::on_frame(const proto::RgbdFrame& frame, std::string* error) {
  if (error) error->clear();
  const slam::Intrinsics k = intrinsics_of(frame);
  if (!pipeline_) {
    const std::string why = start_pipeline(k);
    if (!why.empty()) return lost_update(frame, why, error);
  }
  if (!same_camera(k, intrinsics_)) {
    // The map is built with the first frame's camera model: a frame with another one (a streamer
    // restarted with another calibration) would be tracked with the wrong projection and its error
    // would be put silently into the map. Refused with the reason; a new map takes the new
    // camera.
    return lost_update(frame,
                       "slam-link: frame refused: its camera (" + describe(k) +
                           ") is not the one this map is built with (" + describe(intrinsics_) +
                           "); start a new map for a new camera",
                       error);
  }
  if (!resume_error_.empty()) return lost_update(frame, resume_error_, error);
  if (!map_load_error_.empty() && frames_ == 0 && error) *error = map_load_error_;
  std::string why;
  auto f = to_frame(frame, &why);
  if (!f) return lost_update(frame, why, error);
  const std::int64_t index = f->index;
  try {
    pipeline_->submit(std::move(*f));
  } catch (const std::exception& e) {  // one bad frame must not end the flight's map
    return lost_update(frame, std::string("slam-link: pipeline threw: ") + e.what(), error);
  }
  ++frames_;
  auto rec = pipeline_->record(index);
  if (!rec || !rec->ok)
    return lost_update(
        frame, "slam-link: frame rejected: " + (rec ? rec->error : std::string("no record")),
        error);
  return pose_update(frame, *rec, error);
}

proto::PoseUpdate SlamLinkSession::pose_update(const proto::RgbdFrame& frame,
                                               const slam::FrameRecord& rec, std::string* error) {
  const auto T_world_cam = pose_to_wire(rec.T_world_cam);
  const auto T_prev_cur = pose_to_wire(rec.T_prev_cur);
  // The pose as put on the wire before pose_to_wire (quaternion straight from the matrix): when
  // the codec refuses it, the old server failed to encode its reply and closed the connection.
  std::string raw_refusal;
  {
    proto::PoseUpdate raw;
    raw.T_world_cam = raw_pose(rec.T_world_cam);
    raw.T_prev_cur = raw_pose(rec.T_prev_cur);
    raw_refusal = proto::validate(proto::Message{raw});
  }
  if (!T_world_cam || !T_prev_cur) {
    std::ostringstream m;
    m << "slam-link: pose of frame " << rec.index
      << " cannot be sent (non-finite or not a rotation): T_world_cam\n"
      << rec.T_world_cam.matrix() << "\nT_prev_cur\n"
      << rec.T_prev_cur.matrix();
    return lost_update(frame, m.str(), error);
  }
  proto::PoseUpdate u;
  u.pair_sequence = frame.pair_sequence;
  u.timestamp_us = frame.rgb.header.capture_timestamp_us;
  u.tracking_state = to_wire(rec.state);
  u.T_world_cam = *T_world_cam;
  u.T_prev_cur = *T_prev_cur;
  u.is_keyframe = rec.keyframe;
  u.inlier_count = static_cast<std::uint32_t>(rec.inliers);
  u.map_correction_count = static_cast<std::uint32_t>(rec.map_corrections);
  map_corrections_ = u.map_correction_count;
  if (rec.state == slam::TrackingState::kTracking) last_good_ = *T_world_cam;
  if (!raw_refusal.empty()) {
    ++repaired_;
    if (error) {
      std::ostringstream m;
      m.precision(17);
      m << "slam-link: pose of frame " << rec.index
        << " re-normalised for the wire (as computed the codec refuses it: " << raw_refusal
        << "; T_world_cam q_xyzw " << raw_pose(rec.T_world_cam).q_xyzw[0] << " "
        << raw_pose(rec.T_world_cam).q_xyzw[1] << " " << raw_pose(rec.T_world_cam).q_xyzw[2] << " "
        << raw_pose(rec.T_world_cam).q_xyzw[3] << ", T_prev_cur q_xyzw "
        << raw_pose(rec.T_prev_cur).q_xyzw[0] << " " << raw_pose(rec.T_prev_cur).q_xyzw[1] << " "
        << raw_pose(rec.T_prev_cur).q_xyzw[2] << " " << raw_pose(rec.T_prev_cur).q_xyzw[3] << ")";
      *error = m.str();
    }
  }
  return u;
}

std::string SlamLinkSession::finish_summary() {
  std::ostringstream m;
  m << frames_ << " frames (" << faulted_ << " answered LOST for a fault)";
  const slam::AccelCounts& a = accel_gate_.counts();
  m << "; accelerometer: " << a.accepted() << " samples used, " << a.ignored() << " ignored (";
  for (std::size_t v = 1; v < slam::kAccelVerdictCount; ++v)
    m << (v > 1 ? ", " : "") << to_string(static_cast<slam::AccelVerdict>(v)) << " "
      << a.by_verdict[v];
  m << ")";
  if (pipeline_) {
    pipeline_->finish();
    const auto s = pipeline_->summary();
    m << ", " << s.keyframes << " keyframes, " << s.loop_closures << " loop closures, mapping "
      << s.mapper_caught_up << " keyframes caught up, " << s.mapper_ba_interrupted
      << " BAs interrupted";
    if (!s.mapping_thread.empty()) m << " (" << s.mapping_thread << ")";
    if (!s.lock_schedule.empty()) m << "; " << s.lock_schedule;
    if (!map_load_error_.empty()) m << "; " << map_load_error_;
    if (!resume_error_.empty()) m << "; " << resume_error_;
    if (!map_files_.checkpoint_path.empty()) {
      m << "; " << s.checkpoints_written << " map checkpoints (slowest " << s.checkpoint_max_ms
        << " ms)";
      if (!s.checkpoint_error.empty()) m << ", last failure: " << s.checkpoint_error;
    }
    if (!map_files_.save_path.empty()) {
      std::string err;
      if (pipeline_->save_map(map_files_.save_path, &err))
        m << "; map saved to " << map_files_.save_path;
      else
        m << "; map NOT saved: " << err;
    }
    if (!map_files_.tables_dir.empty()) {
      std::string err = tables_error_;
      if (err.empty() && pipeline_->finish_tables(&err))
        m << "; tables written to " << map_files_.tables_dir;
      else
        m << "; tables NOT written: " << err;
    }
  }
  return m.str();
}

}  // namespace rgbdquad::slamlink
