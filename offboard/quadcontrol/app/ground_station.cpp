// The quad-control hub: see ground_station.hpp.
#include "app/ground_station.hpp"

#include <algorithm>
#include <chrono>

#include "app/thread_setup.hpp"
#include "core/geometry.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr std::int64_t kUsPerMs = 1000;
constexpr int kMaxRtPriority = 99;       // SCHED_RR's highest priority on Linux
constexpr int kCommandPriorityStep = 2;  // firmware link above the SLAM link (and its tracking)
}  // namespace

CraftPoseTrackerOptions GroundStationOptions::tracker() const {
  return CraftPoseTrackerOptions{floor, mount_pitch_down_deg, floor_search_frames,
                                 controller.estimator};
}

bool GroundStationOptions::is_valid(std::string* error) const {
  if (!controller.is_valid(error)) return false;
  if (!floor.is_valid(error)) return false;
  if (!map.is_valid(error)) return false;
  if (!(mount_pitch_down_deg >= 0.0 && mount_pitch_down_deg < 90.0))
    return reject(error, "camera.mount_pitch_down_deg must be in [0, 90)");
  if (floor_search_frames < 1 || floor_pixel_step < 1 || map_pixel_step < 1)
    return reject(error, "floor/map steps must be >= 1");
  if (!(max_depth_m > 0.0)) return reject(error, "map.max_depth_m must be > 0");
  if (control_period_ms < 5 || control_period_ms > 200)
    return reject(error, "control_period_ms must be in [5, 200]");
  if (slam_mode != "server" && slam_mode != "in-process")
    return reject(error, "slam.mode must be 'server' or 'in-process'");
  if (!slam_server.is_valid(error)) return false;
  if (std::string e; !realtime.is_valid(&e)) return reject(error, "realtime." + e);
  return true;
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
      trajectory_(options.trajectory_max_points),
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
}

void GroundStation::start() {
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
        stream_.set_error("SLAM link: " + slam_error);
        return;
      }
      slam_ready_ = true;
    }
    if (!frame) {
      if (stop_) return;
      std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
      stream_.set_error(error);
      if (error == "replay finished") return;
      continue;
    }
    on_frame(*frame);
    slam_->submit(*frame);  // dropped when SLAM is busy (thesis behaviour)
  }
}

void GroundStation::on_frame(CameraFrame& frame) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  take_frame(frame);
}

void GroundStation::take_frame(CameraFrame& frame) {
  stream_.on_frame(frame.received_us, frame.link_latency_ms);
  images_.set_frame(frame);
  if (log_) log_->frame(frame.sequence, frame.capture_us, frame.received_us, frame.link_latency_ms);
  if (recorder_) {
    recorder_->frame(frame.sequence, frame.capture_us, frame.received_us, frame.link_latency_ms,
                     stream_.fps(), frame.rgb, frame.depth, frame.intrinsics, frame.rgb_encoded,
                     frame.depth_encoded);
  }
  if (auto imu = imu_replies_.nearest(frame.received_us, options_.imu_match_window_us)) {
    imu_match_dt_ms_ = static_cast<double>(imu->first - frame.received_us) / kUsPerMs;
  } else {
    imu_match_dt_ms_.reset();
  }
  if (options_.imu_rotation_prior)
    frame.q_ned_cam =
        tracker_.camera_attitude_at(frame.capture_us, options_.attitude_match_window_us);
}

void GroundStation::control_loop() {
  slam::name_current_thread("qc-control");
  auto next = std::chrono::steady_clock::now();
  while (!stop_) {
    next += std::chrono::milliseconds(options_.control_period_ms);
    std::this_thread::sleep_until(next);
    control_step(monotonic_now_us());  // the control thread's edge: the clock is read here
  }
}

void GroundStation::control_step(std::int64_t now_us) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  feed_estimate(now_us);
  last_stick_ = controller_.update(now_us);
  last_pwm_ = to_pwm(last_stick_, spec_.pwm, apm_input());
  if (recorder_) record_command(now_us, 0, false);  // no craft: state events only, nothing is sent
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
                             to_string(st.state), frame.q_ned_cam});
}

void GroundStation::on_slam(const SlamResult& result, const CameraFrame& frame) {
  // The command is computed and sent on the link's thread, after this one released the lock.
  // The SLAM thread's edge: the clock is read here and passed in.
  if (apply_slam_result(monotonic_now_us(), result, frame) && firmware_) firmware_->notify_pose();
}

bool GroundStation::apply_slam_result(std::int64_t now, const SlamResult& result,
                                      const CameraFrame& frame) {
  // Floor plane search on the first frames (outside the lock: RANSAC takes a few ms; fit_floor()
  // reads only the tracker's options).
  std::optional<FloorPlane> found;
  bool need_floor;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    need_floor = tracker_.searching_floor() && result.tracking;
  }
  if (need_floor)
    found =
        tracker_.fit_floor(camera_points(frame, options_.floor_pixel_step, options_.max_depth_m));
  std::vector<Eigen::Vector3d> cam_points;
  if (result.tracking)
    cam_points = camera_points(frame, options_.map_pixel_step, options_.max_depth_m);

  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  last_slam_ = result;
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
  trajectory_.add(update.pose.x_m, update.pose.y_m);
  map_.add_frame(frame, cam_points, T_floor_cam);
  if (recorder_ && recorder_->map_due(now)) recorder_->map(MapRecord{now, map_.map().cloud()});
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

nlohmann::json GroundStation::state_json(std::int64_t now_us) {
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
  snap.taken_us = now_us;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    snap.controller = controller_.status();
    snap.pose = tracker_.pose();
    snap.map_correction_count = tracker_.map_correction_count();
    snap.stick = last_stick_;
    snap.pwm = last_pwm_;
    snap.source = source_->describe();
    snap.frames = stream_.frames();
    snap.fps = stream_.fps();
    snap.sequence = images_.sequence();
    snap.stream_latency_ms = stream_.latency_ms();
    snap.source_error = stream_.error();
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
    const FloorMap& map = map_.map();
    snap.map_origin_x_m = map.origin_x_m();
    snap.map_origin_y_m = map.origin_y_m();
    snap.map_resolution_m = map.resolution_m();
    snap.map_width_cells = map.width_cells();
    snap.map_height_cells = map.height_cells();
    snap.map_revision = map_.revision();
    snap.cloud_points = map.cloud().size();
    snap.trajectory = trajectory_.decimated();
  }
  return to_json(snap);
}

namespace {
nlohmann::json slam_json(const StationSnapshot& snap) {
  const SlamStats& slam_stats = snap.slam_stats;
  const SlamLinkStatus& slam_link = snap.slam_link;
  return {{"link", snap.slam_link_name},
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
}

nlohmann::json firmware_json(const StationSnapshot& snap) {
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
                {"max_link_pause_ms", fw->max_link_pause_ms},
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
  return fwj;
}

nlohmann::json estimator_json(const StationSnapshot& snap) {
  if (snap.estimate) {
    const StateEstimate& e = *snap.estimate;
    const EstimatorStats& es = snap.estimator_stats;
    return {{"enabled", snap.estimator_enabled},
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
  }
  return {{"enabled", snap.estimator_enabled}};
}

}  // namespace

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
  j["manoeuvre_active"] = st.manoeuvre_active;
  j["manoeuvres_done"] = st.manoeuvres_done;
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
  j["slam"] = slam_json(snap);
  j["firmware"] = firmware_json(snap);
  j["estimator"] = estimator_json(snap);
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

std::optional<std::string> GroundStation::rgb_jpeg() {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return images_.rgb_jpeg();
}

std::optional<std::string> GroundStation::depth_png() {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return images_.depth_png();
}

std::string GroundStation::map_png() {
  std::vector<std::uint8_t> rgb;
  int n;
  {
    std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
    rgb = map_.map().render_rgb();
    n = map_.map().width_cells();
  }
  return StationMap::png_of_render(std::move(rgb), n);  // encoded outside the lock
}

nlohmann::json GroundStation::cloud_json(std::size_t max_points) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return map_.cloud_json(max_points, tracker_.pose());
}

std::string GroundStation::map_ply() {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return map_.ply();
}

std::string GroundStation::command(std::int64_t now_us, OperatorCommand cmd) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.command(now_us, cmd);
}

std::string GroundStation::waypoint(std::int64_t now_us, double x_m, double y_m) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.set_waypoint(now_us, x_m, y_m);
}

std::string GroundStation::manual(std::int64_t now_us, double forward_m, double left_m, double up_m,
                                  double yaw_ccw_deg) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.nudge(now_us, forward_m, left_m, up_m, yaw_ccw_deg);
}

std::string GroundStation::manoeuvre(std::int64_t now_us, const ManoeuvreRequest& request) {
  std::lock_guard<slam::PriorityInheritanceMutex> lock(mutex_);
  return controller_.manoeuvre(now_us, request);
}

}  // namespace rgbdquad::quadcontrol
