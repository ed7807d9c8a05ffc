// The quad-control hub: see ground_station.hpp.
#include "app/ground_station.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/thread_setup.hpp"
#include "core/geometry.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kFpsEmaWeight = 0.2;      // frame-to-frame fps, smoothed over ~5 frames
constexpr double kDepthDisplayMaxM = 5.0;  // greyscale: 0 m white .. 5 m black (Kinect range)
constexpr std::int64_t kUsPerMs = 1000;
constexpr int kMaxRtPriority = 99;       // SCHED_RR's highest priority on Linux
constexpr int kCommandPriorityStep = 2;  // firmware link above the SLAM link (and its tracking)

/// The map's points of one frame: camera points (m) into the floor frame, coloured by the RGB
/// pixel they project to (grey where the projection leaves the image or the image is not BGR).
std::vector<ColouredPoint> coloured_floor_points(const CameraFrame& frame,
                                                 const std::vector<Eigen::Vector3d>& cam_points,
                                                 const Eigen::Isometry3d& T_floor_cam) {
  std::vector<ColouredPoint> world;
  world.reserve(cam_points.size());
  const auto& k = frame.intrinsics;
  for (const auto& p : cam_points) {
    const Eigen::Vector3d w = T_floor_cam * p;
    const int u = static_cast<int>(std::lround(p.x() * k.fx_px / p.z() + k.cx_px));
    const int v = static_cast<int>(std::lround(p.y() * k.fy_px / p.z() + k.cy_px));
    ColouredPoint cp{w.cast<float>(), 128, 128, 128};
    if (u >= 0 && v >= 0 && u < frame.rgb.cols && v < frame.rgb.rows &&
        frame.rgb.type() == CV_8UC3) {
      const auto& bgr = frame.rgb.at<cv::Vec3b>(v, u);
      cp.r = bgr[2];
      cp.g = bgr[1];
      cp.b = bgr[0];
    }
    world.push_back(cp);
  }
  return world;
}

nlohmann::json pose_json(const CraftPose& p) {
  return {{"x_m", p.x_m}, {"y_m", p.y_m}, {"z_m", p.z_m}, {"yaw_deg", p.yaw_deg}};
}
}  // namespace

CraftPoseTrackerOptions GroundStationOptions::tracker() const {
  return CraftPoseTrackerOptions{floor, mount_pitch_down_deg, floor_search_frames,
                                 controller.estimator};
}

std::string GroundStationOptions::validate() const {
  if (auto e = controller.validate(); !e.empty()) return e;
  if (auto e = floor.validate(); !e.empty()) return e;
  if (auto e = map.validate(); !e.empty()) return e;
  if (!(mount_pitch_down_deg >= 0.0 && mount_pitch_down_deg < 90.0))
    return "camera.mount_pitch_down_deg must be in [0, 90)";
  if (floor_search_frames < 1 || floor_pixel_step < 1 || map_pixel_step < 1)
    return "floor/map steps must be >= 1";
  if (!(max_depth_m > 0.0)) return "map.max_depth_m must be > 0";
  if (control_period_ms < 5 || control_period_ms > 200)
    return "control_period_ms must be in [5, 200]";
  if (slam_mode != "server" && slam_mode != "in-process")
    return "slam.mode must be 'server' or 'in-process'";
  if (auto e = slam_server.validate(); !e.empty()) return e;
  if (auto e = realtime.validate(); !e.empty()) return "realtime." + e;
  return {};
}

GroundStation::GroundStation(GroundStationOptions options, std::unique_ptr<FrameSource> source,
                             std::optional<FirmwareLinkOptions> firmware, ControlSpec spec,
                             rgbd_control::Key key, std::unique_ptr<FlightLog> log,
                             std::unique_ptr<FlightRecorder> recorder)
    : options_(options),
      spec_(spec),
      source_(std::move(source)),
      controller_(options.controller),
      tracker_(options.tracker()),
      map_(options.map),
      log_(std::move(log)),
      recorder_(std::move(recorder)) {
  last_pwm_ = to_pwm(StickCommand{}, spec_.pwm);
  if (firmware) {
    firmware->thread_priority = options_.realtime;
    // Above the SLAM thread: SCHED_RR threads of equal priority take turns in 100 ms slices, so a
    // command (~1 ms of work, due every 11-50 ms, failsafe at 250 ms) must never wait behind a
    // CPU-bound tracker (seen under load: 170-270 ms without a command -> the firmware's failsafe).
    firmware->thread_priority.rt_priority =
        std::min(kMaxRtPriority, options_.realtime.rt_priority + kCommandPriorityStep);
    firmware_ = std::make_unique<FirmwareLink>(
        *firmware, spec_, key,
        [this](std::int64_t t, std::uint32_t seq) { return command_at(t, seq); },
        [this](std::int64_t t, const rgbd_control::Reply& r) { on_reply(t, r); });
  }
  frame_thread_ = std::thread([this] { frame_loop(); });
  if (!firmware_) control_thread_ = std::thread([this] { control_loop(); });
}

GroundStation::~GroundStation() {
  stop_ = true;
  if (frame_thread_.joinable()) frame_thread_.join();
  if (control_thread_.joinable()) control_thread_.join();
  slam_.reset();  // frame thread joined: nobody submits; this joins the SLAM thread
  firmware_.reset();
}

void GroundStation::frame_loop() {
  slam::name_current_thread("qc-frame");
  raise_this_thread(options_.realtime, "frame");
  while (!stop_) {
    std::string error;
    auto frame = source_->next(stop_, &error);
    if (frame && !slam_ready_.load()) {
      // The SLAM link needs the camera's intrinsics: created on the first frame.
      std::string slam_error;
      auto callback = [this](const SlamResult& r, const CameraFrame& f) { on_slam(r, f); };
      if (options_.slam_mode == "server") {
        SlamServerOptions server = options_.slam_server;
        server.thread_priority = options_.realtime;
        slam_ = std::make_unique<SlamServerClient>(server, callback);
      } else {
        slam_ = InProcessSlam::create(frame->intrinsics, callback, options_.realtime, &slam_error);
      }
      if (!slam_) {
        std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
        source_error_ = "SLAM link: " + slam_error;
        return;
      }
      slam_ready_ = true;
    }
    if (!frame) {
      if (stop_) return;
      std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
      source_error_ = error;
      if (error == "replay finished") return;
      continue;
    }
    {
      std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
      if (last_frame_us_ > 0 && frame->received_us > last_frame_us_) {
        const double inst = 1e6 / static_cast<double>(frame->received_us - last_frame_us_);
        fps_ = frames_ <= 1 ? inst : (1.0 - kFpsEmaWeight) * fps_ + kFpsEmaWeight * inst;
      }
      last_frame_us_ = frame->received_us;
      ++frames_;
      stream_latency_ms_ = frame->link_latency_ms;
      latest_frame_ = *frame;
      if (log_)
        log_->frame(frame->sequence, frame->capture_us, frame->received_us, frame->link_latency_ms);
      if (recorder_) {
        recorder_->frame(frame->sequence, frame->capture_us, frame->received_us,
                         frame->link_latency_ms, fps_, frame->rgb, frame->depth, frame->intrinsics,
                         frame->rgb_encoded, frame->depth_encoded);
      }
      if (auto imu = imu_replies_.nearest(frame->received_us, options_.imu_match_window_us)) {
        imu_match_dt_ms_ = static_cast<double>(imu->first - frame->received_us) / kUsPerMs;
      } else {
        imu_match_dt_ms_.reset();
      }
      if (options_.imu_rotation_prior)
        frame->q_ned_cam =
            tracker_.camera_attitude_at(frame->capture_us, options_.attitude_match_window_us);
    }
    slam_->submit(*frame);  // dropped when SLAM is busy (thesis behaviour)
  }
}

void GroundStation::control_loop() {
  slam::name_current_thread("qc-control");
  auto next = std::chrono::steady_clock::now();
  while (!stop_) {
    next += std::chrono::milliseconds(options_.control_period_ms);
    std::this_thread::sleep_until(next);
    const std::int64_t now = monotonic_now_us();
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    feed_estimate(now);
    last_stick_ = controller_.update(now);
    last_pwm_ = to_pwm(last_stick_, spec_.pwm, apm_input());
    if (recorder_) record_command(now, 0, false);  // no craft: state events only, nothing is sent
  }
}

std::optional<PwmCommand> GroundStation::command_at(std::int64_t now_us, std::uint32_t seq) {
  LoggedCommand logged;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    feed_estimate(now_us);
    last_stick_ = controller_.update(now_us);
    last_pwm_ = to_pwm(last_stick_, spec_.pwm, apm_input());
    if (recorder_) record_command(now_us, seq, !last_stick_.hand_over_to_failsafe);
    if (last_stick_.hand_over_to_failsafe) return std::nullopt;
    if (!log_) return last_pwm_;
    logged = LoggedCommand{seq,       now_us,           to_string(controller_.status().state),
                           last_pwm_, pose_capture_us_, pose_us_};
  }
  log_->command(logged);
  return logged.pwm;
}

void GroundStation::record_command(std::int64_t now_us, std::uint32_t seq, bool sent) {
  const ControllerStatus& st = controller_.status();
  const std::string state = to_string(st.state);
  recorder_->status(now_us, state, st.last_event);
  if (sent)
    recorder_->command(
        CommandRecord{seq, now_us, state, last_stick_, last_pwm_, pose_capture_us_, pose_us_});
}

void GroundStation::record_pose(const SlamResult& result, const CameraFrame& frame,
                                std::int64_t now_us, bool tracking,
                                const Eigen::Isometry3d& T_floor_cam) {
  const ControllerStatus& st = controller_.status();
  recorder_->pose(PoseRecord{frame.sequence, frame.capture_us, frame.received_us, now_us, tracking,
                             result.state, result.inliers, result.latency_ms, result.session,
                             T_floor_cam, tracker_.pose().value_or(CraftPose{}), st.setpoint,
                             to_string(st.state)});
}

std::vector<Eigen::Vector3d> GroundStation::depth_points(const CameraFrame& f, int step) const {
  std::vector<Eigen::Vector3d> pts;
  if (f.depth.type() != CV_16UC1) return pts;
  const auto& k = f.intrinsics;
  for (int v = 0; v < f.depth.rows; v += step) {
    const auto* row = f.depth.ptr<std::uint16_t>(v);
    for (int u = 0; u < f.depth.cols; u += step) {
      if (row[u] == 0) continue;
      const double z = row[u] / k.depth_units_per_m;
      if (z > options_.max_depth_m) continue;
      pts.emplace_back((u - k.cx_px) * z / k.fx_px, (v - k.cy_px) * z / k.fy_px, z);
    }
  }
  return pts;
}

void GroundStation::on_slam(const SlamResult& result, const CameraFrame& frame) {
  // The command is computed and sent on the link's thread, after this one released the lock.
  if (apply_slam_result(result, frame) && firmware_) firmware_->notify_pose();
}

bool GroundStation::apply_slam_result(const SlamResult& result, const CameraFrame& frame) {
  // Floor plane search on the first frames (outside the lock: RANSAC takes a few ms; fit_floor()
  // reads only the tracker's options).
  std::optional<FloorPlane> found;
  bool need_floor;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    need_floor = tracker_.searching_floor() && result.tracking;
  }
  if (need_floor) found = tracker_.fit_floor(depth_points(frame, options_.floor_pixel_step));
  std::vector<Eigen::Vector3d> cam_points;
  if (result.tracking) cam_points = depth_points(frame, options_.map_pixel_step);

  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  last_slam_ = result;
  const std::int64_t now = monotonic_now_us();
  const CraftPoseUpdate update = tracker_.update(
      now,
      SlamPoseInput{result.tracking, result.T_world_cam, result.session,
                    result.map_correction_count, frame.capture_us, frame.received_us},
      found);
  controller_.on_pose(update.controller.sample, update.controller.velocity_m_per_s);
  if (!update.tracking) {
    if (log_)
      log_->pose(LoggedPose{frame.sequence, frame.capture_us, frame.received_us, now, false});
    if (recorder_) record_pose(result, frame, now, false, Eigen::Isometry3d::Identity());
    return false;
  }
  const Eigen::Isometry3d& T_floor_cam = update.T_floor_cam;
  pose_capture_us_ = frame.capture_us;
  pose_us_ = now;
  if (log_) {
    log_->pose(LoggedPose{frame.sequence, frame.capture_us, frame.received_us, now, true,
                          T_floor_cam, update.pose.yaw_deg});
  }
  if (recorder_) record_pose(result, frame, now, true, T_floor_cam);
  if (trajectory_.size() >= options_.trajectory_max_points) trajectory_.erase(trajectory_.begin());
  trajectory_.push_back({update.pose.x_m, update.pose.y_m});

  map_.add_points(coloured_floor_points(frame, cam_points, T_floor_cam));
  if (recorder_ && recorder_->map_due(now)) recorder_->map(MapRecord{now, map_.cloud()});
  ++map_revision_;
  return true;
}

void GroundStation::on_reply(std::int64_t received_us, const rgbd_control::Reply& reply) {
  if (recorder_) recorder_->reply(received_us, reply);
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  imu_replies_.push(received_us, reply);
  if (auto imu = imu_sample_from_reply(reply, received_us)) tracker_.on_imu(*imu);
}

void GroundStation::feed_estimate(std::int64_t now_us) {
  if (auto feed = tracker_.estimate_feed(now_us))
    controller_.on_pose(feed->sample, feed->velocity_m_per_s);
}

nlohmann::json GroundStation::state_json() {
  StationSnapshot snap;
  // The links' own stats (thread-safe copies) outside the lock, then one copy of the hub's state
  // under it; the JSON is built after the lock is released.
  const bool slam_ready = slam_ready_.load();
  snap.slam_link_name = slam_ready ? slam_->name() : "starting";
  if (slam_ready) {
    snap.slam_stats = slam_->stats();
    snap.slam_link = slam_->link_status();
  }
  if (firmware_) snap.firmware = firmware_->stats();
  snap.taken_us = monotonic_now_us();
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    snap.controller = controller_.status();
    snap.pose = tracker_.pose();
    snap.map_correction_count = tracker_.map_correction_count();
    snap.stick = last_stick_;
    snap.pwm = last_pwm_;
    snap.source = source_->describe();
    snap.frames = frames_;
    snap.fps = fps_;
    snap.sequence = latest_frame_ ? latest_frame_->sequence : -1;
    snap.stream_latency_ms = stream_latency_ms_;
    snap.source_error = source_error_;
    if (last_slam_) {
      snap.slam_state = last_slam_->state;
      snap.slam_inliers = last_slam_->inliers;
    }
    snap.imu_match_dt_ms = imu_match_dt_ms_;
    snap.estimator_enabled = options_.controller.estimator.enabled;
    snap.estimate = tracker_.last_estimate();
    snap.estimator_stats = tracker_.estimator().stats();
    snap.estimates_flown = tracker_.estimates_flown();
    if (recorder_) snap.recording = recorder_->stats();
    snap.floor = tracker_.floor();
    snap.floor_fallback = tracker_.floor_fallback();
    snap.map_origin_x_m = map_.origin_x_m();
    snap.map_origin_y_m = map_.origin_y_m();
    snap.map_resolution_m = map_.resolution_m();
    snap.map_width_cells = map_.width_cells();
    snap.map_height_cells = map_.height_cells();
    snap.map_revision = map_revision_;
    snap.cloud_points = map_.cloud().size();
    const std::size_t stride = std::max<std::size_t>(1, trajectory_.size() / 500);
    snap.trajectory.reserve(trajectory_.size() / stride + 1);
    for (std::size_t i = 0; i < trajectory_.size(); i += stride)
      snap.trajectory.push_back(trajectory_[i]);
  }
  return to_json(snap);
}

nlohmann::json to_json(const StationSnapshot& snap) {
  const ControllerStatus& st = snap.controller;
  nlohmann::json j;
  j["state"] = to_string(st.state);
  j["last_event"] = st.last_event;
  j["tracking"] = st.tracking;
  j["rejected_poses"] = st.rejected_poses;
  j["map_resets"] = st.map_resets;  // declared map corrections flown
  j["refused_map_corrections"] = st.refused_map_corrections;
  j["map_correction_count"] = snap.map_correction_count;
  j["facing_waypoint"] = st.facing_waypoint;
  j["pose"] = snap.pose ? pose_json(*snap.pose) : nlohmann::json(nullptr);
  j["setpoint"] = pose_json(st.setpoint);
  j["waypoint"] = st.waypoint ? nlohmann::json{{"x_m", st.waypoint->x_m}, {"y_m", st.waypoint->y_m}}
                              : nlohmann::json(nullptr);
  const StickCommand& stick = snap.stick;
  const PwmCommand& pwm = snap.pwm;
  j["command"] = {{"roll_pct", stick.roll_pct},
                  {"pitch_pct", stick.pitch_pct},
                  {"yaw_pct", stick.yaw_pct},
                  {"throttle_pct", stick.throttle_pct},
                  {"armed", stick.armed},
                  {"pwm_us", {pwm.roll_us, pwm.pitch_us, pwm.throttle_us, pwm.yaw_us}}};
  j["stream"] = {{"source", snap.source},
                 {"frames", snap.frames},
                 {"fps", snap.fps},
                 {"sequence", snap.sequence},
                 {"latency_ms", snap.stream_latency_ms},
                 {"error", snap.source_error}};
  const SlamStats& slam_stats = snap.slam_stats;
  const SlamLinkStatus& slam_link = snap.slam_link;
  j["slam"] = {{"link", snap.slam_link_name},
               {"state", snap.slam_state},
               {"inliers", snap.slam_inliers},
               {"submitted", slam_stats.submitted},
               {"processed", slam_stats.processed},
               {"dropped_busy", slam_stats.dropped_busy},
               {"latency_ms", slam_stats.last_latency_ms},
               {"error", slam_stats.last_error},
               // New maps (1 in a healthy flight), resumed reconnects, broken connections.
               {"session_id", slam_link.session_id},
               {"sessions_started", slam_link.sessions_started},
               {"resumes", slam_link.resumes},
               {"disconnects", slam_link.disconnects},
               {"last_disconnect", slam_link.last_disconnect}};
  const std::optional<FirmwareLinkStats>& fw = snap.firmware;
  nlohmann::json fwj = {{"enabled", fw.has_value()}};
  if (fw) {
    const bool connected =
        fw->last_reply_us > 0 && snap.taken_us - fw->last_reply_us < 1000 * kUsPerMs;
    fwj.update({{"connected", connected},
                {"latency_ms", fw->last_latency_ms},
                {"mean_latency_ms", fw->mean_latency_ms},
                {"sent", fw->sent},
                {"ok", fw->ok},
                {"timeouts", fw->timeouts},
                {"http_errors", fw->http_errors},
                {"stale", fw->stale},
                {"connect_errors", fw->connect_errors},
                {"seq", fw->seq},
                {"pose_driven", fw->pose_driven},
                {"keep_alives", fw->keep_alives},
                {"withheld", fw->withheld},
                {"command_gaps", fw->command_gaps},
                {"max_command_gap_ms", fw->max_command_gap_ms},
                {"last_error", fw->last_error}});
    if (fw->last_reply) {
      const auto& r = *fw->last_reply;
      fwj["reply"] = {{"status", r.status},
                      {"state", r.state},
                      {"fw", r.fw},
                      {"out_us", r.out_us},
                      {"att_mrad", r.att_mrad},
                      {"att_age_ms", r.att_age_ms ? nlohmann::json(*r.att_age_ms) : nullptr},
                      {"imu_raw", r.imu_raw}};
    }
    fwj["imu_match_dt_ms"] =
        snap.imu_match_dt_ms ? nlohmann::json(*snap.imu_match_dt_ms) : nlohmann::json(nullptr);
  }
  j["firmware"] = fwj;
  if (snap.estimate) {
    const StateEstimate& e = *snap.estimate;
    const EstimatorStats& es = snap.estimator_stats;
    j["estimator"] = {{"enabled", snap.estimator_enabled},
                      {"valid", e.valid},
                      {"why_invalid", e.why_invalid},
                      {"imu_aided", e.imu_aided},
                      {"age_ms", e.age_ms},
                      {"pose", pose_json(e.pose)},
                      {"velocity_m_per_s",
                       {e.velocity_m_per_s.x(), e.velocity_m_per_s.y(), e.velocity_m_per_s.z()}},
                      {"position_sigma_m",
                       {e.position_sigma_m.x(), e.position_sigma_m.y(), e.position_sigma_m.z()}},
                      {"steps_flown", snap.estimates_flown},
                      {"imu_samples", es.imu_samples},
                      {"poses_fused", es.poses_fused},
                      {"poses_out_of_order", es.poses_out_of_order},
                      {"poses_rejected", es.poses_rejected},
                      {"poses_too_old", es.poses_too_old},
                      {"resets", es.resets}};
  } else {
    j["estimator"] = {{"enabled", snap.estimator_enabled}};
  }
  j["recording"] = snap.recording ? to_json(*snap.recording) : nlohmann::json{{"enabled", false}};
  const std::optional<FloorPlane>& floor = snap.floor;
  j["floor"] = {{"found", floor.has_value()},
                {"fallback", snap.floor_fallback},
                {"height_m", floor ? floor->d_m : 0.0},
                {"inlier_fraction", floor ? floor->inlier_fraction : 0.0}};
  j["map"] = {{"origin_x_m", snap.map_origin_x_m},     {"origin_y_m", snap.map_origin_y_m},
              {"resolution_m", snap.map_resolution_m}, {"width_cells", snap.map_width_cells},
              {"height_cells", snap.map_height_cells}, {"revision", snap.map_revision},
              {"cloud_points", snap.cloud_points}};
  nlohmann::json traj = nlohmann::json::array();
  for (const auto& p : snap.trajectory) traj.push_back(p);
  j["trajectory"] = traj;
  return j;
}

ApmStickInput GroundStation::apm_input() const {
  const ControlConfig& c = options_.controller;
  return ApmStickInput{c.apm_stick_deadzone_us, c.apm_throttle_deadband_us, c.hover_throttle_pct};
}

void GroundStation::invalidate_image_caches_if_new_frame() {
  if (cache_sequence_ == latest_frame_->sequence) return;
  rgb_jpeg_cache_.reset();
  depth_png_cache_.reset();
  cache_sequence_ = latest_frame_->sequence;
}

std::optional<std::string> GroundStation::rgb_jpeg() {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  if (!latest_frame_) return std::nullopt;
  invalidate_image_caches_if_new_frame();
  if (!rgb_jpeg_cache_) {
    std::vector<std::uint8_t> buf;
    if (!cv::imencode(".jpg", latest_frame_->rgb, buf, {cv::IMWRITE_JPEG_QUALITY, 80}))
      return std::nullopt;
    rgb_jpeg_cache_ = std::string(buf.begin(), buf.end());
  }
  return rgb_jpeg_cache_;
}

std::optional<std::string> GroundStation::depth_png() {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  if (!latest_frame_) return std::nullopt;
  invalidate_image_caches_if_new_frame();
  if (!depth_png_cache_) {
    // 16-bit depth as greyscale: near = bright, far = dark, no reading = black.
    const cv::Mat& d = latest_frame_->depth;
    cv::Mat grey(d.rows, d.cols, CV_8UC1);
    const double units_max = kDepthDisplayMaxM * latest_frame_->intrinsics.depth_units_per_m;
    for (int v = 0; v < d.rows; ++v) {
      const auto* in = d.ptr<std::uint16_t>(v);
      auto* out = grey.ptr<std::uint8_t>(v);
      for (int u = 0; u < d.cols; ++u) {
        out[u] = in[u] == 0
                     ? 0
                     : static_cast<std::uint8_t>(255.0 - 235.0 * std::min(1.0, in[u] / units_max));
      }
    }
    std::vector<std::uint8_t> buf;
    if (!cv::imencode(".png", grey, buf)) return std::nullopt;
    depth_png_cache_ = std::string(buf.begin(), buf.end());
  }
  return depth_png_cache_;
}

std::string GroundStation::map_png() {
  std::vector<std::uint8_t> rgb;
  int n;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    rgb = map_.render_rgb();
    n = map_.width_cells();
  }
  cv::Mat img(n, n, CV_8UC3, rgb.data());
  cv::Mat bgr;
  cv::cvtColor(img, bgr, cv::COLOR_RGB2BGR);
  std::vector<std::uint8_t> buf;
  cv::imencode(".png", bgr, buf);
  return std::string(buf.begin(), buf.end());
}

nlohmann::json GroundStation::cloud_json(std::size_t max_points) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  const auto& cloud = map_.cloud();
  nlohmann::json pts = nlohmann::json::array();
  const std::size_t stride = std::max<std::size_t>(
      1, (cloud.size() + max_points - 1) / std::max<std::size_t>(1, max_points));
  for (std::size_t i = 0; i < cloud.size(); i += stride) {
    const auto& p = cloud[i];
    pts.push_back({std::round(p.p_world.x() * 1000) / 1000, std::round(p.p_world.y() * 1000) / 1000,
                   std::round(p.p_world.z() * 1000) / 1000, p.r, p.g, p.b});
  }
  nlohmann::json pose = tracker_.pose() ? pose_json(*tracker_.pose()) : nlohmann::json(nullptr);
  return {{"points", pts}, {"total", cloud.size()}, {"pose", pose}};
}

std::string GroundStation::map_ply() {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return map_.to_ply();
}

std::string GroundStation::command(OperatorCommand cmd) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.command(monotonic_now_us(), cmd);
}

std::string GroundStation::waypoint(double x_m, double y_m) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.set_waypoint(monotonic_now_us(), x_m, y_m);
}

std::string GroundStation::manual(double forward_m, double left_m, double up_m,
                                  double yaw_ccw_deg) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.nudge(monotonic_now_us(), forward_m, left_m, up_m, yaw_ccw_deg);
}

}  // namespace rgbdquad::quadcontrol
