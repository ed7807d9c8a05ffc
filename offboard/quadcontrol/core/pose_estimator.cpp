// IMU + delayed SLAM pose fusion: see pose_estimator.hpp for the design and the contract.
#include "core/pose_estimator.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/geometry.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kUsPerS = 1e6;
constexpr double kUsPerMs = 1000.0;
constexpr double kMssPerMg = 9.80665e-3;  // RAW_IMU accelerometer in mg (ArduPilot sends mg)
constexpr double kRadPerMrad = 1e-3;      // control reply att_mrad
constexpr double kGravityMss = 9.80665;   // standard gravity: the accelerometer's 1 g at rest

std::map<std::string, double*> scalar_fields(EstimatorOptions& o) {
  return {{"max_prediction_ms", &o.max_prediction_ms},
          {"max_position_sigma_m", &o.max_position_sigma_m},
          {"max_innovation_m", &o.max_innovation_m},
          {"pose_sigma_m", &o.pose_sigma_m},
          {"imu_accel_noise_mss_per_sqrt_hz", &o.imu_accel_noise_mss_per_sqrt_hz},
          {"no_imu_accel_noise_mss_per_sqrt_hz", &o.no_imu_accel_noise_mss_per_sqrt_hz},
          {"bias_walk_mss_per_sqrt_s", &o.bias_walk_mss_per_sqrt_s},
          {"initial_velocity_sigma_m_per_s", &o.initial_velocity_sigma_m_per_s},
          {"initial_bias_sigma_mss", &o.initial_bias_sigma_mss},
          {"imu_timeout_ms", &o.imu_timeout_ms},
          {"history_ms", &o.history_ms}};
}

bool finite(const CraftPose& p) {
  return std::isfinite(p.x_m) && std::isfinite(p.y_m) && std::isfinite(p.z_m) &&
         std::isfinite(p.yaw_deg);
}

double wrap_rad(double a) { return wrap_deg(a * kDegPerRad) / kDegPerRad; }
}  // namespace

bool EstimatorOptions::is_valid(std::string* error) const {
  EstimatorOptions copy = *this;
  for (auto& [name, value] : scalar_fields(copy)) {
    if (!std::isfinite(*value) || *value <= 0.0)
      return reject(error, "controller.estimator." + name + " must be finite and > 0");
  }
  if (history_ms < max_prediction_ms)
    return reject(error, "controller.estimator.history_ms must be >= max_prediction_ms");
  return true;
}

std::string load_estimator_options(const nlohmann::json& j, EstimatorOptions& options) {
  if (!j.is_object()) return "controller.estimator: expected an object";
  auto scalars = scalar_fields(options);
  for (const auto& [key, value] : j.items()) {
    if (key == "enabled") {
      if (!value.is_boolean()) return "controller.estimator.enabled: expected true or false";
      options.enabled = value.get<bool>();
    } else if (auto it = scalars.find(key); it != scalars.end()) {
      if (!value.is_number()) return "controller.estimator." + key + ": expected a number";
      *it->second = value.get<double>();
    } else {
      return "controller.estimator." + key + ": unknown key";
    }
  }
  return {};
}

nlohmann::json to_json(const EstimatorOptions& options) {
  EstimatorOptions copy = options;
  nlohmann::json j = {{"enabled", options.enabled}};
  for (auto& [name, value] : scalar_fields(copy)) j[name] = *value;
  return j;
}

std::optional<ImuSample> imu_sample_from_reply(const rgbd_control::Reply& reply,
                                               std::int64_t received_us) {
  if (!reply.imu_age_ms || !reply.att_age_ms) return std::nullopt;
  ImuSample s;
  const auto newest_age_ms = std::min(*reply.imu_age_ms, *reply.att_age_ms);
  s.t_us = received_us - static_cast<std::int64_t>(newest_age_ms) * 1000;
  s.attitude_t_us = received_us - static_cast<std::int64_t>(*reply.att_age_ms) * 1000;
  s.specific_force_frd_mss =
      Eigen::Vector3d(reply.imu_raw[0], reply.imu_raw[1], reply.imu_raw[2]) * kMssPerMg;
  s.roll_rad = reply.att_mrad[0] * kRadPerMrad;
  s.pitch_rad = reply.att_mrad[1] * kRadPerMrad;
  s.yaw_rad = reply.att_mrad[2] * kRadPerMrad;
  return s;
}

std::int64_t CaptureClock::to_local(std::int64_t capture_us, std::int64_t received_us) {
  offsets_us_.push_back(received_us - capture_us);
  while (offsets_us_.size() > window_) offsets_us_.pop_front();
  return *peek(capture_us);
}

std::optional<std::int64_t> CaptureClock::peek(std::int64_t capture_us) const {
  if (offsets_us_.empty()) return std::nullopt;
  return capture_us + *std::min_element(offsets_us_.begin(), offsets_us_.end());
}

const char* to_string(FuseOutcome outcome) {
  switch (outcome) {
    case FuseOutcome::kFused:
      return "fused";
    case FuseOutcome::kInitialised:
      return "initialised";
    case FuseOutcome::kRejectedJump:
      return "rejected: innovation beyond max_innovation_m";
    case FuseOutcome::kTooOld:
      return "rejected: older than the history";
    case FuseOutcome::kNonFinite:
      return "rejected: non-finite";
  }
  return "?";
}

PoseEstimator::PoseEstimator(EstimatorOptions options) : options_(options) {
  if (std::string error; !options_.is_valid(&error)) throw std::invalid_argument(error);
}

void PoseEstimator::reset() {
  history_.clear();
  pending_input_.reset();
  newest_pose_.reset();
  newest_pose_capture_us_ = 0;
  last_imu_raw_.reset();
  yaw_offset_rad_.reset();
}

bool PoseEstimator::shift_frame(const Eigen::Vector3d& delta_m) {
  if (history_.empty() || !delta_m.allFinite()) return false;
  for (Event& e : history_) {
    for (int k = 0; k < 3; ++k) e.posterior[k].x(0) += delta_m(k);
    if (e.pose) {
      e.pose->x_m += delta_m(0);
      e.pose->y_m += delta_m(1);
      e.pose->z_m += delta_m(2);
    }
  }
  if (newest_pose_) {
    newest_pose_->x_m += delta_m(0);
    newest_pose_->y_m += delta_m(1);
    newest_pose_->z_m += delta_m(2);
  }
  ++stats_.frame_shifts;
  return true;
}

Eigen::Vector3d PoseEstimator::floor_accel(const LevelInput& in) const {
  // Level frame (forward, left, up) -> floor frame by the craft's heading in the floor frame:
  // SLAM yaw (ccw) = offset - APM yaw (cw).
  const double yaw = *yaw_offset_rad_ - in.apm_yaw_rad;
  const double c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Vector3d& a = in.accel_flu_mss;
  return {c * a.x() - s * a.y(), s * a.x() + c * a.y(), a.z()};
}

bool PoseEstimator::input_fresh(const std::optional<LevelInput>& input, std::int64_t t_us) const {
  return input && yaw_offset_rad_ &&
         static_cast<double>(t_us - input->t_us) <= options_.imu_timeout_ms * kUsPerMs;
}

void PoseEstimator::predict_axis(Axis& a, double dt_s, double accel_mss,
                                 double noise_density) const {
  // x = [p, v, b]; the true acceleration is the measured one minus the bias, held over dt:
  //   p' = p + v dt + (u - b) dt^2/2,  v' = v + (u - b) dt,  b' = b.
  Eigen::Matrix3d F;
  F << 1, dt_s, -0.5 * dt_s * dt_s, 0, 1, -dt_s, 0, 0, 1;
  const Eigen::Vector3d B(0.5 * dt_s * dt_s, dt_s, 0.0);
  a.x = F * a.x + B * accel_mss;
  // Continuous white acceleration noise of spectral density q (m^2/s^3), integrated exactly over
  // dt; the bias walks with its own density.
  const double q = noise_density * noise_density;
  const double qb = options_.bias_walk_mss_per_sqrt_s * options_.bias_walk_mss_per_sqrt_s;
  const double dt2 = dt_s * dt_s, dt3 = dt2 * dt_s;
  Eigen::Matrix3d Q = Eigen::Matrix3d::Zero();
  Q(0, 0) = q * dt3 / 3.0;
  Q(0, 1) = Q(1, 0) = q * dt2 / 2.0;
  Q(1, 1) = q * dt_s;
  Q(2, 2) = qb * dt_s;
  a.P = F * a.P * F.transpose() + Q;
}

void PoseEstimator::propagate(State& s, std::int64_t from_us, std::int64_t to_us,
                              const std::optional<LevelInput>& input) const {
  if (to_us <= from_us) return;
  const double dt_s = static_cast<double>(to_us - from_us) / kUsPerS;
  // The input is fresh at the start of the step or not at all (a step never spans a new sample).
  const bool fresh = input_fresh(input, from_us);
  const Eigen::Vector3d u = fresh ? floor_accel(*input) : Eigen::Vector3d::Zero();
  const double density = fresh ? options_.imu_accel_noise_mss_per_sqrt_hz
                               : options_.no_imu_accel_noise_mss_per_sqrt_hz;
  for (int i = 0; i < 3; ++i) predict_axis(s[i], dt_s, u[i], density);
}

bool PoseEstimator::predict(const ImuSample& sample) {
  const Eigen::Vector3d& f = sample.specific_force_frd_mss;
  if (!f.allFinite() || !std::isfinite(sample.roll_rad) || !std::isfinite(sample.pitch_rad) ||
      !std::isfinite(sample.yaw_rad)) {
    ++stats_.imu_dropped;
    return false;
  }
  // Replies repeat the newest reading until the next one arrives (RAW_IMU 10 Hz, ATTITUDE 25 Hz,
  // replies 20-50 Hz) and so carry the same sample time: not newer -> dropped. (A repeat stamped a
  // few ms later by reply jitter only re-applies the input in effect: harmless.) A firmware that
  // stops receiving telemetry keeps repeating the reading with a growing age: never newer.
  if (last_imu_raw_ && sample.t_us <= last_imu_raw_->t_us) {
    ++stats_.imu_dropped;
    return false;
  }
  last_imu_raw_ = sample;
  ++stats_.imu_samples;
  // Level frame: a = Ry(pitch) Rx(roll) f + g (NED, heading-aligned), then forward/left/up.
  const double cr = std::cos(sample.roll_rad), sr = std::sin(sample.roll_rad);
  const double cp = std::cos(sample.pitch_rad), sp = std::sin(sample.pitch_rad);
  const Eigen::Vector3d r(f.x(), cr * f.y() - sr * f.z(), sr * f.y() + cr * f.z());  // Rx(roll) f
  const Eigen::Vector3d ned(cp * r.x() + sp * r.z(), r.y(), -sp * r.x() + cp * r.z() + kGravityMss);
  LevelInput in{sample.t_us, Eigen::Vector3d(ned.x(), -ned.y(), -ned.z()), sample.yaw_rad};
  if (history_.empty()) {
    // Not initialised (no pose yet): remembered as the input in effect for the first pose.
    pending_input_ = in;
    return true;
  }
  Event e;
  e.t_us = sample.t_us;
  e.imu = in;
  const auto pos = std::upper_bound(history_.begin(), history_.end(), e.t_us,
                                    [](std::int64_t t, const Event& ev) { return t < ev.t_us; });
  if (pos == history_.begin()) {  // older than the whole history: nothing to apply it to
    ++stats_.imu_dropped;
    return false;
  }
  const std::size_t idx = static_cast<std::size_t>(pos - history_.begin());
  history_.insert(pos, e);
  replay_from(idx);
  trim_history();
  return true;
}

void PoseEstimator::replay_from(std::size_t from) {
  const Eigen::Matrix<double, 1, 3> H(1.0, 0.0, 0.0);
  const double r = options_.pose_sigma_m * options_.pose_sigma_m;
  for (std::size_t i = std::max<std::size_t>(from, 1); i < history_.size(); ++i) {
    const Event& prev = history_[i - 1];
    Event& e = history_[i];
    State s = prev.posterior;
    propagate(s, prev.t_us, e.t_us, prev.input);
    if (e.pose) {
      const double z[3] = {e.pose->x_m, e.pose->y_m, e.pose->z_m};
      for (int k = 0; k < 3; ++k) {
        Axis& a = s[k];
        const double innovation = z[k] - a.x(0);
        const double S = a.P(0, 0) + r;
        const Eigen::Vector3d K = a.P.col(0) / S;
        a.x += K * innovation;
        // Joseph form keeps P symmetric and positive for any gain.
        const Eigen::Matrix3d I_KH = Eigen::Matrix3d::Identity() - K * H;
        a.P = I_KH * a.P * I_KH.transpose() + K * r * K.transpose();
      }
    }
    e.input = e.imu ? e.imu : prev.input;
    e.posterior = s;
  }
}

void PoseEstimator::trim_history() {
  const std::int64_t horizon_us = static_cast<std::int64_t>(options_.history_ms * kUsPerMs);
  while (history_.size() > 1 && history_.back().t_us - history_[1].t_us > horizon_us)
    history_.pop_front();
}

FuseOutcome PoseEstimator::fuse_pose(const CraftPose& pose, std::int64_t capture_us) {
  if (!finite(pose)) return FuseOutcome::kNonFinite;
  const bool expired = newest_pose_ && static_cast<double>(capture_us - newest_pose_capture_us_) >
                                           options_.max_prediction_ms * kUsPerMs;
  if (history_.empty() || expired) {
    if (expired) ++stats_.resets;
    const std::optional<LevelInput> input =
        history_.empty() ? pending_input_ : history_.back().input;
    history_.clear();
    Event e;
    e.t_us = capture_us;
    e.pose = pose;
    e.input = input;
    const double p0 = options_.pose_sigma_m * options_.pose_sigma_m;
    const double v0 =
        options_.initial_velocity_sigma_m_per_s * options_.initial_velocity_sigma_m_per_s;
    const double b0 = options_.initial_bias_sigma_mss * options_.initial_bias_sigma_mss;
    const double z[3] = {pose.x_m, pose.y_m, pose.z_m};
    for (int k = 0; k < 3; ++k) {
      e.posterior[k].x = Eigen::Vector3d(z[k], 0.0, 0.0);
      e.posterior[k].P = Eigen::Vector3d(p0, v0, b0).asDiagonal();
    }
    history_.push_back(e);
    newest_pose_ = pose;
    newest_pose_capture_us_ = capture_us;
    if (input) yaw_offset_rad_ = wrap_rad(pose.yaw_deg / kDegPerRad + input->apm_yaw_rad);
    ++stats_.poses_fused;
    return FuseOutcome::kInitialised;
  }
  if (capture_us < history_.front().t_us) {
    ++stats_.poses_too_old;
    return FuseOutcome::kTooOld;
  }
  const auto pos = std::upper_bound(history_.begin(), history_.end(), capture_us,
                                    [](std::int64_t t, const Event& ev) { return t < ev.t_us; });
  const std::size_t idx = static_cast<std::size_t>(pos - history_.begin());  // >= 1
  const Event& prev = history_[idx - 1];
  State predicted = prev.posterior;
  propagate(predicted, prev.t_us, capture_us, prev.input);
  const Eigen::Vector3d innovation(pose.x_m - predicted[0].x(0), pose.y_m - predicted[1].x(0),
                                   pose.z_m - predicted[2].x(0));
  if (innovation.norm() > options_.max_innovation_m) {
    ++stats_.poses_rejected;
    return FuseOutcome::kRejectedJump;
  }
  const bool newest = capture_us >= newest_pose_capture_us_;
  if (!newest) ++stats_.poses_out_of_order;
  if (newest && prev.input) {
    // The heading offset between the APM's yaw and SLAM's, at this capture (the APM yaw in effect).
    yaw_offset_rad_ = wrap_rad(pose.yaw_deg / kDegPerRad + prev.input->apm_yaw_rad);
  }
  Event e;
  e.t_us = capture_us;
  e.pose = pose;
  history_.insert(pos, e);
  replay_from(idx);
  if (newest) {
    newest_pose_ = pose;
    newest_pose_capture_us_ = capture_us;
  }
  trim_history();
  ++stats_.poses_fused;
  return FuseOutcome::kFused;
}

StateEstimate PoseEstimator::estimate(std::int64_t now_us) const {
  StateEstimate out;
  if (history_.empty() || !newest_pose_) {
    out.why_invalid = "no pose fused yet";
    return out;
  }
  const Event& last = history_.back();
  State s = last.posterior;
  propagate(s, last.t_us, now_us, last.input);
  out.pose.x_m = s[0].x(0);
  out.pose.y_m = s[1].x(0);
  out.pose.z_m = s[2].x(0);
  out.velocity_m_per_s = Eigen::Vector3d(s[0].x(1), s[1].x(1), s[2].x(1));
  out.position_sigma_m =
      Eigen::Vector3d(std::sqrt(s[0].P(0, 0)), std::sqrt(s[1].P(0, 0)), std::sqrt(s[2].P(0, 0)));
  out.age_ms = static_cast<double>(now_us - newest_pose_capture_us_) / kUsPerMs;
  out.imu_aided = input_fresh(last.input, now_us);
  // Heading now: the newest pose's, turned by the APM's yaw change since (gyro-based over < 1 s).
  out.pose.yaw_deg = newest_pose_->yaw_deg;
  if (out.imu_aided)
    out.pose.yaw_deg = wrap_deg((*yaw_offset_rad_ - last.input->apm_yaw_rad) * kDegPerRad);
  const double sigma_h = std::max(out.position_sigma_m.x(), out.position_sigma_m.y());
  if (out.age_ms > options_.max_prediction_ms) {
    out.why_invalid = "newest pose older than max_prediction_ms";
  } else if (!(sigma_h <= options_.max_position_sigma_m)) {
    out.why_invalid = "position sigma above max_position_sigma_m";
  } else if (!finite(out.pose) || !out.velocity_m_per_s.allFinite()) {
    out.why_invalid = "non-finite state";
  }
  out.valid = out.why_invalid.empty();
  return out;
}

}  // namespace rgbdquad::quadcontrol
