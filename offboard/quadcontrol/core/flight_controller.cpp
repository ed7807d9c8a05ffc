// Flight state machine and position controller: see flight_controller.hpp.
#include "core/flight_controller.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/geometry.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kMmPerM = 1000.0;
constexpr double kUsPerMs = 1000.0;
constexpr double kUsPerS = 1e6;

bool finite_pose(const CraftPose& p) {
  return std::isfinite(p.x_m) && std::isfinite(p.y_m) && std::isfinite(p.z_m) &&
         std::isfinite(p.yaw_deg);
}

/// Distance and speed along a trapezoidal profile (rates ramped at accel, capped at max_rate) of
/// `total` at `t_s` after its start; done once the whole distance is covered.
struct ProfilePoint {
  double distance = 0.0;
  double rate = 0.0;
  bool done = false;
};
ProfilePoint trapezoid(double total, double max_rate, double accel, double t_s) {
  if (total <= 0.0 || max_rate <= 0.0 || accel <= 0.0) return {total, 0.0, true};
  double peak = max_rate;
  double t_ramp = peak / accel;
  double t_cruise = (total - peak * t_ramp) / peak;
  if (t_cruise < 0.0) {  // too short to reach the rate: a triangle
    peak = std::sqrt(total * accel);
    t_ramp = peak / accel;
    t_cruise = 0.0;
  }
  const double t_end = 2.0 * t_ramp + t_cruise;
  if (t_s <= 0.0) return {0.0, 0.0, false};
  if (t_s >= t_end) return {total, 0.0, true};
  if (t_s < t_ramp) return {0.5 * accel * t_s * t_s, accel * t_s, false};
  if (t_s < t_ramp + t_cruise) return {0.5 * peak * t_ramp + peak * (t_s - t_ramp), peak, false};
  const double left_s = t_end - t_s;
  return {total - 0.5 * accel * left_s * left_s, accel * left_s, false};
}

bool flying(FlightState s) {
  return s == FlightState::kTakeOff || s == FlightState::kHold || s == FlightState::kGoToWaypoint ||
         s == FlightState::kLostHold || s == FlightState::kLand;
}
}  // namespace

const char* to_string(FlightState state) {
  switch (state) {
    case FlightState::kDisarmed:
      return "disarmed";
    case FlightState::kArmed:
      return "armed";
    case FlightState::kTakeOff:
      return "take-off";
    case FlightState::kHold:
      return "hold";
    case FlightState::kGoToWaypoint:
      return "go-to-waypoint";
    case FlightState::kLostHold:
      return "lost-hold";
    case FlightState::kLand:
      return "land";
  }
  return "?";
}

const char* to_string(OperatorCommand command) {
  switch (command) {
    case OperatorCommand::kArm:
      return "arm";
    case OperatorCommand::kDisarm:
      return "disarm";
    case OperatorCommand::kTakeOff:
      return "takeoff";
    case OperatorCommand::kLand:
      return "land";
  }
  return "?";
}

static EnvelopeLimits envelope_limits(const ControlConfig& c) {
  EnvelopeLimits limits;
  limits.max_distance_from_home_m = c.max_distance_from_home_m;
  // Manual steps never took the setpoint below twice the motor-stop height (a hold that low would
  // stop the motors as soon as the estimate dips); that is the envelope's floor.
  limits.min_height_m = 2.0 * c.motor_stop_height_m;
  limits.max_height_m = c.max_height_m;
  return limits;
}

FlightController::FlightController(ControlConfig config)
    : config_(config),
      envelope_(envelope_limits(config)),
      roll_(config.roll),
      pitch_(config.pitch),
      yaw_(config.yaw),
      throttle_(config.throttle),
      cascade_(config.cascade,
               std::min(config.roll.output_limit_pct, config.pitch.output_limit_pct)) {
  if (std::string error; !config_.is_valid(&error)) throw std::invalid_argument(error);
  status_.last_event = "start-up";
}

bool FlightController::has_fresh_pose(std::int64_t now_us) const {
  if (!pose_ || !pose_->tracking) return false;
  return static_cast<double>(now_us - pose_->received_us) <= config_.pose_timeout_ms * kUsPerMs;
}

bool FlightController::set_setpoint_position(double x_m, double y_m, double z_m, SetpointKind kind,
                                             bool* clamped) {
  const auto c = envelope_.contain(SetpointPosition{x_m, y_m, z_m}, kind);
  if (!c) return false;
  status_.setpoint.x_m = c->position.x_m;
  status_.setpoint.y_m = c->position.y_m;
  status_.setpoint.z_m = c->position.z_m;
  if (clamped) *clamped = c->clamped;
  return true;
}

void FlightController::reset_pids() {
  roll_.reset();
  pitch_.reset();
  yaw_.reset();
  throttle_.reset();
  cascade_.reset();
  pid_pose_us_.reset();
}

void FlightController::enter(FlightState state, std::int64_t now_us, const std::string& why) {
  status_.state = state;
  status_.last_event = std::string(to_string(state)) + ": " + why;
  // Every transition ends a manoeuvre where its setpoint is (a lost-hold holds there after).
  manoeuvre_.reset();
  status_.manoeuvre_active = false;
  ff_x_m_per_s_ = ff_y_m_per_s_ = ff_yaw_deg_per_s_ = 0.0;
  state_entered_us_ = now_us;
  if (state != FlightState::kGoToWaypoint) {
    status_.waypoint.reset();
    status_.facing_waypoint = false;
  }
  if (state == FlightState::kLand) {
    // The landing starts at most at the ceiling (a craft above it sinks at once).
    const double start_m = pose_ && pose_->tracking ? pose_->pose.z_m : status_.setpoint.z_m;
    const auto c = envelope_.contain(SetpointPosition{0.0, 0.0, start_m}, SetpointKind::kLanding);
    land_start_height_m_ = c ? c->position.z_m : envelope_.limits().max_height_m;
    land_floor_reached_us_.reset();
    handed_over_us_.reset();
    low_since_us_.reset();
    // Land where the craft is: an unfinished go-to or manual step is abandoned.
    if (pose_ && pose_->tracking) {
      status_.setpoint.x_m = pose_->pose.x_m;
      status_.setpoint.y_m = pose_->pose.y_m;
    }
  }
  if (state == FlightState::kDisarmed || state == FlightState::kArmed) reset_pids();
  // The APM was armed by the gesture: leaving armed/flight needs the disarm gesture.
  disarm_gesture_pending_ = state == FlightState::kDisarmed;
}

std::string FlightController::command(std::int64_t now_us, OperatorCommand cmd) {
  const FlightState s = status_.state;
  switch (cmd) {
    case OperatorCommand::kArm:
      if (s != FlightState::kDisarmed) return "arm: only when disarmed";
      enter(FlightState::kArmed, now_us, "operator armed");
      return {};
    case OperatorCommand::kDisarm:
      if (flying(s)) return "disarm: refused in flight (land first)";
      if (s == FlightState::kDisarmed) return "disarm: already disarmed";
      enter(FlightState::kDisarmed, now_us, "operator disarmed");
      return {};
    case OperatorCommand::kTakeOff: {
      if (s != FlightState::kArmed) return "takeoff: only when armed";
      if (static_cast<double>(now_us - state_entered_us_) < config_.arm_gesture_ms * kUsPerMs) {
        return "takeoff: arming gesture still in progress";
      }
      if (!has_fresh_pose(now_us)) return "takeoff: no tracked pose";
      reset_pids();
      const CraftPose& p = pose_->pose;  // finite: on_pose() counts non-finite poses as lost
      envelope_.set_home(p.x_m, p.y_m);
      status_.setpoint.yaw_deg = p.yaw_deg;
      // The ramp starts where the craft is, kept inside [min, max] height of the envelope.
      if (!set_setpoint_position(p.x_m, p.y_m, p.z_m, SetpointKind::kTakeOff))
        return "takeoff: non-finite pose";
      takeoff_start_height_m_ = status_.setpoint.z_m;
      enter(FlightState::kTakeOff, now_us, "operator take-off");
      return {};
    }
    case OperatorCommand::kLand:
      if (!flying(s)) return "land: not flying";
      if (s == FlightState::kLand) return "land: already landing";
      enter(FlightState::kLand, now_us, "operator land");
      return {};
  }
  return "unknown command";
}

std::string FlightController::set_waypoint(std::int64_t now_us, double x_m, double y_m) {
  if (!std::isfinite(x_m) || !std::isfinite(y_m)) return "waypoint: non-finite coordinates";
  if (status_.state != FlightState::kHold && status_.state != FlightState::kGoToWaypoint) {
    return std::string("waypoint: only in hold or go-to (now ") + to_string(status_.state) + ")";
  }
  if (!has_fresh_pose(now_us)) return "waypoint: no tracked pose";
  const CraftPose& p = pose_->pose;
  const double distance_m = std::hypot(x_m - p.x_m, y_m - p.y_m);
  if (distance_m > config_.max_waypoint_distance_m)
    return "waypoint: further than max_waypoint_distance_m";
  if (std::string why = envelope_.check_waypoint(x_m, y_m); !why.empty()) return why;
  status_.waypoint = Waypoint{x_m, y_m};
  manoeuvre_.reset();
  status_.manoeuvre_active = false;
  ff_x_m_per_s_ = ff_y_m_per_s_ = ff_yaw_deg_per_s_ = 0.0;
  if (distance_m < config_.turn_skip_distance_m) {
    // Close goal: keep the heading (position never drives yaw), move at once.
    status_.facing_waypoint = true;
    set_setpoint_position(x_m, y_m, status_.setpoint.z_m, SetpointKind::kHold);
  } else {
    status_.facing_waypoint = false;
    // Turn where the craft is (a craft that drifted outside the fence is held at its edge).
    set_setpoint_position(p.x_m, p.y_m, status_.setpoint.z_m, SetpointKind::kHold);
    status_.setpoint.yaw_deg = bearing_deg(p.x_m, p.y_m, x_m, y_m);
  }
  status_.state = FlightState::kGoToWaypoint;
  status_.last_event = "go-to-waypoint: operator clicked the map";
  state_entered_us_ = now_us;
  return {};
}

std::string FlightController::nudge(std::int64_t, double forward_m, double left_m, double up_m,
                                    double yaw_ccw_deg) {
  for (double v : {forward_m, left_m, up_m, yaw_ccw_deg}) {
    if (!std::isfinite(v)) return "manual: non-finite step";
  }
  for (double v : {forward_m, left_m, up_m}) {
    if (std::abs(v) > config_.max_manual_step_m)
      return "manual: step larger than max_manual_step_m";
  }
  if (std::abs(yaw_ccw_deg) > config_.max_manual_yaw_step_deg)
    return "manual: turn larger than max_manual_yaw_step_deg";
  const FlightState s = status_.state;
  if (s != FlightState::kHold && s != FlightState::kGoToWaypoint)
    return "manual: only in hold or go-to";
  const double c = std::cos(status_.setpoint.yaw_deg / kDegPerRad);
  const double sn = std::sin(status_.setpoint.yaw_deg / kDegPerRad);
  bool clamped = false;
  if (!set_setpoint_position(status_.setpoint.x_m + c * forward_m - sn * left_m,
                             status_.setpoint.y_m + sn * forward_m + c * left_m,
                             status_.setpoint.z_m + up_m, SetpointKind::kHold, &clamped)) {
    return "manual: step leads to a non-finite setpoint";
  }
  status_.setpoint.yaw_deg = wrap_deg(status_.setpoint.yaw_deg + yaw_ccw_deg);
  manoeuvre_.reset();
  status_.manoeuvre_active = false;
  ff_x_m_per_s_ = ff_y_m_per_s_ = ff_yaw_deg_per_s_ = 0.0;
  status_.state = FlightState::kHold;
  status_.waypoint.reset();
  status_.facing_waypoint = false;
  status_.last_event =
      clamped ? "hold: manual step, clamped to the flight envelope" : "hold: manual step";
  return {};
}

std::string FlightController::manoeuvre(std::int64_t now_us, const ManoeuvreRequest& r) {
  for (double v : {r.forward_m, r.left_m, r.yaw_ccw_deg, r.speed_m_per_s, r.yaw_rate_deg_per_s}) {
    if (!std::isfinite(v)) return "manoeuvre: non-finite value";
  }
  if (status_.state != FlightState::kHold) return "manoeuvre: only in hold";
  if (!has_fresh_pose(now_us)) return "manoeuvre: no tracked pose";
  if (manoeuvre_) return "manoeuvre: one is in progress";
  const double distance_m = std::hypot(r.forward_m, r.left_m);
  if (distance_m == 0.0 && r.yaw_ccw_deg == 0.0) return "manoeuvre: nothing to do";
  if (distance_m > config_.max_manoeuvre_distance_m)
    return "manoeuvre: move longer than max_manoeuvre_distance_m";
  if (std::abs(r.yaw_ccw_deg) > config_.max_manoeuvre_turn_deg)
    return "manoeuvre: turn larger than max_manoeuvre_turn_deg";
  if (distance_m > 0.0 &&
      !(r.speed_m_per_s > 0.0 && r.speed_m_per_s <= config_.max_manoeuvre_speed_m_per_s)) {
    return "manoeuvre: speed_m_per_s must be in (0, max_manoeuvre_speed_m_per_s]";
  }
  if (r.yaw_ccw_deg != 0.0 && !(r.yaw_rate_deg_per_s > 0.0 &&
                                r.yaw_rate_deg_per_s <= config_.max_manoeuvre_yaw_rate_deg_per_s)) {
    return "manoeuvre: yaw_rate_deg_per_s must be in (0, max_manoeuvre_yaw_rate_deg_per_s]";
  }
  ActiveManoeuvre m;
  m.start_us = now_us;
  m.x0_m = status_.setpoint.x_m;
  m.y0_m = status_.setpoint.y_m;
  m.yaw0_deg = status_.setpoint.yaw_deg;
  const double c = std::cos(m.yaw0_deg / kDegPerRad);
  const double sn = std::sin(m.yaw0_deg / kDegPerRad);
  const double dx = c * r.forward_m - sn * r.left_m;
  const double dy = sn * r.forward_m + c * r.left_m;
  // The end point must be inside the envelope as asked (a manoeuvre is not clamped short).
  const auto end = envelope_.contain(
      SetpointPosition{m.x0_m + dx, m.y0_m + dy, status_.setpoint.z_m}, SetpointKind::kHold);
  if (!end || end->clamped) return "manoeuvre: end point outside the flight envelope";
  if (distance_m > 0.0) {
    m.dir_x = dx / distance_m;
    m.dir_y = dy / distance_m;
  }
  m.distance_m = distance_m;
  m.turn_deg = r.yaw_ccw_deg;
  m.speed_m_per_s = r.speed_m_per_s;
  m.yaw_rate_deg_per_s = r.yaw_rate_deg_per_s;
  manoeuvre_ = m;
  status_.manoeuvre_active = true;
  status_.last_event = "hold: manoeuvre started";
  return {};
}

void FlightController::advance_manoeuvre(std::int64_t now_us) {
  ff_x_m_per_s_ = ff_y_m_per_s_ = ff_yaw_deg_per_s_ = 0.0;
  if (!manoeuvre_ || status_.state != FlightState::kHold) return;
  const ActiveManoeuvre& m = *manoeuvre_;
  const double t_s = static_cast<double>(now_us - m.start_us) / kUsPerS;
  const ProfilePoint move =
      trapezoid(m.distance_m, m.speed_m_per_s, config_.manoeuvre_accel_mss, t_s);
  const ProfilePoint turn = trapezoid(std::abs(m.turn_deg), m.yaw_rate_deg_per_s,
                                      config_.manoeuvre_yaw_accel_deg_per_s2, t_s);
  set_setpoint_position(m.x0_m + m.dir_x * move.distance, m.y0_m + m.dir_y * move.distance,
                        status_.setpoint.z_m, SetpointKind::kHold);
  const double sign = m.turn_deg < 0.0 ? -1.0 : 1.0;
  status_.setpoint.yaw_deg = wrap_deg(m.yaw0_deg + sign * turn.distance);
  ff_x_m_per_s_ = m.dir_x * move.rate;
  ff_y_m_per_s_ = m.dir_y * move.rate;
  ff_yaw_deg_per_s_ = sign * turn.rate;
  if (move.done && turn.done) {
    manoeuvre_.reset();
    status_.manoeuvre_active = false;
    ++status_.manoeuvres_done;
    status_.last_event = "hold: manoeuvre done";
  }
}

void FlightController::on_pose(const PoseSample& sample,
                               std::optional<Velocity3> velocity_m_per_s) {
  PoseSample s = sample;
  if (!finite_pose(s.pose)) s.tracking = false;
  if (velocity_m_per_s && !std::all_of(velocity_m_per_s->begin(), velocity_m_per_s->end(),
                                       [](double v) { return std::isfinite(v); })) {
    velocity_m_per_s.reset();  // the derivative falls back to differencing poses
  }
  pose_velocity_ = velocity_m_per_s;
  if (s.tracking && last_accepted_pose_) {
    // Jump gate: an estimate far from the last accepted one is a SLAM failure (e.g. a false loop
    // closure), not motion. It counts as lost until the estimate comes back near the last accepted
    // pose; if it never does, lost-hold lands blind. No time-based relaxation: a wrong estimate
    // that stays wrong must never be flown on.
    const CraftPose& a = *last_accepted_pose_;
    const double jump_m = std::sqrt((s.pose.x_m - a.x_m) * (s.pose.x_m - a.x_m) +
                                    (s.pose.y_m - a.y_m) * (s.pose.y_m - a.y_m) +
                                    (s.pose.z_m - a.z_m) * (s.pose.z_m - a.z_m));
    // A declared correction (the counter changed, PX4 EKF2's reset counter) is consumed once: the
    // jump is the map moving under the craft, not motion. Setpoints stay in the world frame, so the
    // craft flies to the corrected place under its usual output limits.
    const bool declared = map_correction_count_ && s.map_correction_count != *map_correction_count_;
    if (declared && jump_m <= config_.max_map_correction_m) {
      ++status_.map_resets;
      // No derivative across the jump (it would kick); the integrators keep the hover offset.
      for (Pid* pid : {&roll_, &pitch_, &yaw_, &throttle_}) pid->restart();
      cascade_.restart();
      status_.last_event = std::string(to_string(status_.state)) + ": map correction " +
                           std::to_string(s.map_correction_count) + " declared, re-anchored " +
                           std::to_string(jump_m).substr(0, 4) + " m";
    } else if (declared) {
      s.tracking = false;
      ++status_.rejected_poses;
      ++status_.refused_map_corrections;
      status_.last_event =
          std::string(to_string(status_.state)) + ": declared map correction refused, " +
          std::to_string(jump_m).substr(0, 4) + " m > max_map_correction_m (aliased place?)";
    } else if (jump_m > config_.max_pose_jump_m) {
      s.tracking = false;
      ++status_.rejected_poses;
      status_.last_event = std::string(to_string(status_.state)) + ": pose rejected, jumped " +
                           std::to_string(jump_m).substr(0, 4) + " m (SLAM failure?)";
    }
  }
  if (sample.tracking && finite_pose(sample.pose)) map_correction_count_ = s.map_correction_count;
  if (s.tracking) last_accepted_pose_ = s.pose;
  pose_ = s;
}

double FlightController::unwrap_yaw(double yaw_deg) {
  if (!unwrapped_yaw_deg_) {
    unwrapped_yaw_deg_ = yaw_deg;
  } else {
    *unwrapped_yaw_deg_ += wrap_deg(yaw_deg - last_raw_yaw_deg_);
  }
  last_raw_yaw_deg_ = yaw_deg;
  return *unwrapped_yaw_deg_;
}

StickCommand FlightController::position_control(const PoseSample& sample,
                                                double height_setpoint_m) {
  // The PIDs run once per pose estimate, stamped with its arrival time. update() runs at the
  // command rate (50 Hz) but estimates come at the camera's rate (6-30 Hz): re-running the PIDs on
  // an unchanged measurement would turn the derivative into one spike per frame and zeros in
  // between (and a spike clipped by the output limit loses damping), and would integrate a stale
  // error.
  if (pid_pose_us_ && *pid_pose_us_ == sample.received_us) return pid_cmd_;
  const std::int64_t now_us = sample.received_us;
  const CraftPose& pose = sample.pose;
  StickCommand cmd;
  cmd.armed = true;
  const BodyError e =
      world_to_body(status_.setpoint.x_m - pose.x_m, status_.setpoint.y_m - pose.y_m, pose.yaw_deg);
  // Body-frame PIDs: measurement = craft position relative to the setpoint, in mm. With an
  // estimated velocity its body-frame components are the measurements' rates (mm/s).
  std::optional<double> forward_rate, left_rate, up_rate;
  if (const auto& v = pose_velocity_) {
    const BodyError vb = world_to_body((*v)[0], (*v)[1], pose.yaw_deg);
    forward_rate = vb.forward_m * kMmPerM;
    left_rate = vb.left_m * kMmPerM;
    up_rate = (*v)[2] * kMmPerM;
  }
  if (config_.position_law == PositionLaw::kCascade) {
    std::optional<BodyVector> v_body;
    if (forward_rate && left_rate)
      v_body = BodyVector{*forward_rate / kMmPerM, *left_rate / kMmPerM};
    const BodyError ff = world_to_body(ff_x_m_per_s_, ff_y_m_per_s_, pose.yaw_deg);
    if (auto out = cascade_.update(now_us, BodyVector{e.forward_m, e.left_m}, v_body,
                                   BodyVector{ff.forward_m, ff.left_m})) {
      cmd.pitch_pct = out->forward;  // forward acceleration -> nose down
      cmd.roll_pct = -out->left;     // left acceleration -> roll left
    }
  } else {
    if (auto out = pitch_.update(now_us, 0.0, -e.forward_m * kMmPerM, forward_rate))
      cmd.pitch_pct = *out;
    if (auto out = roll_.update(now_us, 0.0, -e.left_m * kMmPerM, left_rate))
      cmd.roll_pct = -*out;  // left error -> roll left
  }
  // Yaw on a continuous (unwrapped) angle so the derivative never sees a 360 deg jump.
  const double yaw_cont = unwrap_yaw(pose.yaw_deg);
  const double yaw_target = yaw_cont + wrap_deg(status_.setpoint.yaw_deg - pose.yaw_deg);
  // A manoeuvre's turn rate is fed forward as the stick the APM turns at that rate with; the PID
  // only corrects around it (ccw rate -> stick left).
  const double yaw_ff_pct = -ff_yaw_deg_per_s_ / config_.apm_yaw_rate_max_deg_per_s * 100.0;
  if (auto out = yaw_.update(now_us, yaw_target, yaw_cont))
    cmd.yaw_pct = yaw_ff_pct - *out;  // ccw error -> stick left
  double throttle_out = 0.0;
  if (auto out = throttle_.update(now_us, height_setpoint_m * kMmPerM, pose.z_m * kMmPerM, up_rate))
    throttle_out = *out;
  cmd.throttle_pct = std::clamp(config_.hover_throttle_pct + throttle_out, 0.0, 100.0);
  pid_pose_us_ = sample.received_us;
  pid_cmd_ = cmd;
  return cmd;
}

StickCommand FlightController::update(std::int64_t now_us) {
  const bool fresh = has_fresh_pose(now_us);
  status_.tracking = fresh;
  supervise_tracking(now_us, fresh);
  advance_manoeuvre(now_us);
  const StickCommand cmd = command_in_state(now_us, fresh);
  last_throttle_pct_ = cmd.throttle_pct;
  return cmd;
}

void FlightController::supervise_tracking(std::int64_t now_us, bool fresh) {
  const FlightState s = status_.state;
  if ((s == FlightState::kTakeOff || s == FlightState::kHold || s == FlightState::kGoToWaypoint) &&
      !fresh) {
    interrupted_takeoff_ = s == FlightState::kTakeOff;
    interrupted_waypoint_ = s == FlightState::kGoToWaypoint ? status_.waypoint : std::nullopt;
    enter(FlightState::kLostHold, now_us, "tracking lost, holding neutral");
  }
  if (status_.state != FlightState::kLostHold) return;
  if (fresh) {
    resume_after_loss(now_us);
  } else if (static_cast<double>(now_us - state_entered_us_) >= config_.lost_hold_ms * kUsPerMs) {
    enter(FlightState::kLand, now_us, "tracking not back in time, landing blind");
  }
}

void FlightController::resume_after_loss(std::int64_t now_us) {
  // Keep the integrators (the throttle one holds the learned hover offset); a derivative
  // across the gap would be meaningless.
  for (Pid* pid : {&roll_, &pitch_, &yaw_, &throttle_}) pid->restart();
  cascade_.restart();
  pid_pose_us_.reset();
  if (interrupted_takeoff_) {
    // A take-off interrupted (e.g. while the floor is still inside the Kinect's 0.5 m minimum
    // range) climbs on from the setpoint it had reached rather than holding half-way up.
    takeoff_start_height_m_ = status_.setpoint.z_m;
    enter(FlightState::kTakeOff, now_us, "tracking back, climbing on");
  } else {
    enter(FlightState::kHold, now_us, "tracking back");
    if (interrupted_waypoint_) {
      // The operator's waypoint survives a short loss of tracking: turn (if needed) and go on.
      const Waypoint w = *interrupted_waypoint_;
      set_waypoint(now_us, w.x_m, w.y_m);
      status_.last_event = "go-to-waypoint: tracking back, going on";
    }
  }
  interrupted_waypoint_.reset();
}

StickCommand FlightController::command_in_state(std::int64_t now_us, bool fresh) {
  StickCommand cmd;
  const double in_state_ms = static_cast<double>(now_us - state_entered_us_) / kUsPerMs;
  switch (status_.state) {
    case FlightState::kDisarmed:
      if (disarm_gesture_pending_ && in_state_ms < config_.disarm_gesture_ms) {
        cmd.armed = true;
        cmd.yaw_pct = -100.0;  // ArduCopter disarm gesture: throttle 0, yaw full left
      }
      break;
    case FlightState::kArmed:
      cmd.armed = true;
      if (in_state_ms < config_.arm_gesture_ms)
        cmd.yaw_pct = 100.0;  // arming gesture: yaw full right
      break;
    case FlightState::kLostHold:
      cmd.armed = true;
      // Hover as learned so far: the feed-forward plus the throttle integrator (battery sag,
      // weight).
      cmd.throttle_pct = std::clamp(config_.hover_throttle_pct + throttle_.integral(), 0.0, 100.0);
      break;
    case FlightState::kTakeOff:
      cmd = takeoff_step(now_us);
      break;
    case FlightState::kHold:
      cmd = position_control(*pose_, status_.setpoint.z_m);
      break;
    case FlightState::kGoToWaypoint:
      cmd = waypoint_step(now_us);
      break;
    case FlightState::kLand:
      cmd = land_step(now_us, fresh);
      break;
  }
  return cmd;
}

StickCommand FlightController::takeoff_step(std::int64_t now_us) {
  const double elapsed_s = static_cast<double>(now_us - state_entered_us_) / kUsPerS;
  const double ramp_m = takeoff_start_height_m_ + config_.takeoff_climb_rate_m_per_s * elapsed_s;
  set_setpoint_position(status_.setpoint.x_m, status_.setpoint.y_m,
                        std::min(ramp_m, config_.hold_height_m), SetpointKind::kTakeOff);
  const StickCommand cmd = position_control(*pose_, status_.setpoint.z_m);
  if (status_.setpoint.z_m >= config_.hold_height_m &&
      std::abs(pose_->pose.z_m - config_.hold_height_m) <= config_.takeoff_reached_tolerance_m) {
    enter(FlightState::kHold, now_us, "reached hold height");
  }
  return cmd;
}

StickCommand FlightController::waypoint_step(std::int64_t now_us) {
  const CraftPose& p = pose_->pose;
  const Waypoint w = *status_.waypoint;
  if (!status_.facing_waypoint && std::abs(wrap_deg(status_.setpoint.yaw_deg - p.yaw_deg)) <=
                                      config_.face_waypoint_tolerance_deg) {
    status_.facing_waypoint = true;  // turned: now move, heading stays fixed
    set_setpoint_position(w.x_m, w.y_m, status_.setpoint.z_m, SetpointKind::kHold);
  }
  const StickCommand cmd = position_control(*pose_, status_.setpoint.z_m);
  if (status_.facing_waypoint &&
      std::hypot(w.x_m - p.x_m, w.y_m - p.y_m) <= config_.waypoint_reached_m) {
    enter(FlightState::kHold, now_us, "waypoint reached");
  }
  return cmd;
}

StickCommand FlightController::land_step(std::int64_t now_us, bool fresh) {
  StickCommand cmd;
  cmd.armed = true;
  if (fresh && !handed_over_us_) {
    // Tracked: the height setpoint sinks at land_descent_rate_m_per_s and the height PID holds
    // that sink rate. (A thrust ramp alone accelerates the descent when the APM flies thrust,
    // i.e. Stabilize: measured 1.8 m/s touchdowns in the HIL rig.) Below the ground the PID
    // keeps pushing down, so the craft stays put until the motors stop.
    const double elapsed_s = static_cast<double>(now_us - state_entered_us_) / kUsPerS;
    status_.setpoint.z_m =
        std::max(0.0, land_start_height_m_ - config_.land_descent_rate_m_per_s * elapsed_s);
    cmd = position_control(*pose_, status_.setpoint.z_m);
    cmd.armed = true;
    if (status_.setpoint.z_m <= config_.motor_stop_height_m && !land_floor_reached_us_) {
      land_floor_reached_us_ = now_us;
    }
  } else {
    // Blind (no height feedback): hand the craft to the APM's own LAND (barometer, LAND_SPEED)
    // by sending no command: the firmware's failsafe does the hand-over 250 ms later. Latched:
    // the firmware's failsafe refuses arm=1 until disarmed, and the APM is landing anyway.
    // (A blind thrust ramp is a fall in Stabilize: measured 6.6 m/s in the HIL rig.)
    if (!handed_over_us_) {
      handed_over_us_ = now_us;
      status_.last_event = "land: blind, handed over to the craft's failsafe (APM LAND)";
    }
    cmd = StickCommand{};
    cmd.hand_over_to_failsafe = true;
  }
  return land_touchdown(now_us, fresh, cmd);
}

StickCommand FlightController::land_touchdown(std::int64_t now_us, bool fresh, StickCommand cmd) {
  // On the ground = at or below the motor-stop height for land_ground_settle_ms: stopping the
  // motors the moment an estimate first reads that low drops the craft the rest of the way
  // whenever the estimate is a few cm low (measured: 0.82 m/s touchdowns in the HIL rig).
  const bool low = fresh && !handed_over_us_ && pose_->pose.z_m <= config_.motor_stop_height_m;
  if (!low)
    low_since_us_.reset();
  else if (!low_since_us_)
    low_since_us_ = now_us;
  const bool near_ground = low && static_cast<double>(now_us - *low_since_us_) >=
                                      config_.land_ground_settle_ms * kUsPerMs;
  const bool floor_long_enough =
      land_floor_reached_us_ && static_cast<double>(now_us - *land_floor_reached_us_) >=
                                    config_.land_floor_hold_ms * kUsPerMs;
  const bool failsafe_landed = handed_over_us_ && static_cast<double>(now_us - *handed_over_us_) >=
                                                      config_.failsafe_landing_ms * kUsPerMs;
  if (failsafe_landed) {
    // The APM landed and disarmed itself; arm=0 clears the firmware's failsafe latch.
    enter(FlightState::kDisarmed, now_us, "failsafe landing over, firmware disarmed");
    disarm_gesture_pending_ = false;
    cmd = StickCommand{};
  } else if (near_ground || floor_long_enough) {
    enter(FlightState::kDisarmed, now_us,
          near_ground ? "landed, motors stopped" : "landed at the floor, motors stopped");
    cmd = StickCommand{};
    cmd.armed = true;  // disarm gesture starts now (see kDisarmed)
    cmd.yaw_pct = -100.0;
  }
  return cmd;
}

}  // namespace rgbdquad::quadcontrol
