// Cascaded horizontal position law: see cascade_position.hpp.
#include "core/cascade_position.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/geometry.hpp"
#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kGravityMss = 9.80665;
constexpr double kUsPerS = 1e6;
constexpr double kPercent = 100.0;

bool finite(BodyVector v) { return std::isfinite(v.forward) && std::isfinite(v.left); }

/// Limits the length of a horizontal vector (not each axis: a diagonal is no faster).
BodyVector limit_norm(BodyVector v, double max_norm) {
  const double n = std::hypot(v.forward, v.left);
  if (n <= max_norm || n == 0.0) return v;
  return BodyVector{v.forward * max_norm / n, v.left * max_norm / n};
}
}  // namespace

bool CascadeGains::is_valid(std::string* error) const {
  for (double g : {position_kp_per_s, velocity_kp_per_s, velocity_ki_per_s2}) {
    if (!std::isfinite(g) || g < 0.0)
      return reject(error, "controller.cascade gains must be finite and >= 0");
  }
  if (!std::isfinite(integral_limit_mss) || integral_limit_mss < 0.0 ||
      integral_limit_mss > kGravityMss) {
    return reject(error, "controller.cascade.integral_limit_mss must be in [0, 9.8]");
  }
  if (!std::isfinite(max_correction_speed_m_per_s) || max_correction_speed_m_per_s <= 0.0) {
    return reject(error, "controller.cascade.max_correction_speed_m_per_s must be finite and > 0");
  }
  // ArduCopter's ANGLE_MAX range is 10..80 deg.
  if (!(angle_max_deg >= 10.0 && angle_max_deg <= 80.0)) {
    return reject(error, "controller.cascade.angle_max_deg must be in [10, 80]");
  }
  return true;
}

CascadePosition::CascadePosition(CascadeGains gains, double lean_limit_pct)
    : gains_(gains), lean_limit_pct_(lean_limit_pct) {
  if (std::string e; !gains_.is_valid(&e)) throw std::invalid_argument(e);
  if (!std::isfinite(lean_limit_pct) || lean_limit_pct <= 0.0 || lean_limit_pct > kPercent) {
    throw std::invalid_argument("CascadePosition: lean_limit_pct must be in (0, 100]");
  }
}

void CascadePosition::reset() {
  integral_mss_ = {};
  restart();
  terms_ = CascadeTerms{};
}

void CascadePosition::restart() {
  last_error_m_.reset();
  last_time_us_.reset();
}

std::optional<BodyVector> CascadePosition::update(std::int64_t now_us, BodyVector position_error_m,
                                                  std::optional<BodyVector> velocity_m_per_s,
                                                  BodyVector feed_forward_m_per_s) {
  if (!finite(position_error_m) || !finite(feed_forward_m_per_s)) return std::nullopt;
  if (velocity_m_per_s && !finite(*velocity_m_per_s)) return std::nullopt;
  if (last_time_us_ && now_us <= *last_time_us_) return std::nullopt;
  const double dt_s = last_time_us_ ? static_cast<double>(now_us - *last_time_us_) / kUsPerS : 0.0;

  // The craft's velocity: measured, else from the error's change (error = setpoint - craft, and
  // the setpoint moves at the feed-forward velocity). No history: no damping on this one step,
  // as the thesis PID's first derivative.
  BodyVector v{};
  if (velocity_m_per_s) {
    v = *velocity_m_per_s;
  } else if (last_error_m_ && dt_s > 0.0) {
    v.forward =
        feed_forward_m_per_s.forward - (position_error_m.forward - last_error_m_->forward) / dt_s;
    v.left = feed_forward_m_per_s.left - (position_error_m.left - last_error_m_->left) / dt_s;
  } else {
    v = feed_forward_m_per_s;
  }

  const BodyVector correction =
      limit_norm(BodyVector{gains_.position_kp_per_s * position_error_m.forward,
                            gains_.position_kp_per_s * position_error_m.left},
                 gains_.max_correction_speed_m_per_s);
  const BodyVector v_sp{correction.forward + feed_forward_m_per_s.forward,
                        correction.left + feed_forward_m_per_s.left};
  const BodyVector v_err{v_sp.forward - v.forward, v_sp.left - v.left};

  const double angle_max_rad = gains_.angle_max_deg / kDegPerRad;
  const double lean_limit_rad = lean_limit_pct_ / kPercent * angle_max_rad;
  const auto to_stick = [&](double accel_mss) {
    const double lean_rad = std::atan(accel_mss / kGravityMss);
    return std::clamp(lean_rad / angle_max_rad * kPercent, -lean_limit_pct_, lean_limit_pct_);
  };
  // Per axis: integrate unless the output is clamped and the error pushes further out.
  const auto axis = [&](double err, double& integral, bool& clamped) {
    const double candidate = std::clamp(integral + gains_.velocity_ki_per_s2 * err * dt_s,
                                        -gains_.integral_limit_mss, gains_.integral_limit_mss);
    const double unclamped = gains_.velocity_kp_per_s * err + candidate;
    const bool out = std::abs(std::atan(unclamped / kGravityMss)) > lean_limit_rad;
    if (!(out && err * unclamped > 0.0)) integral = candidate;
    const double accel = gains_.velocity_kp_per_s * err + integral;
    clamped = std::abs(std::atan(accel / kGravityMss)) > lean_limit_rad;
    return accel;
  };
  bool clamped_f = false, clamped_l = false;
  const double a_f = axis(v_err.forward, integral_mss_.forward, clamped_f);
  const double a_l = axis(v_err.left, integral_mss_.left, clamped_l);
  const BodyVector stick{to_stick(a_f), to_stick(a_l)};

  terms_ =
      CascadeTerms{v_sp, v, integral_mss_, BodyVector{a_f, a_l}, stick, clamped_f || clamped_l};
  last_error_m_ = position_error_m;
  last_time_us_ = now_us;
  return stick;
}

}  // namespace rgbdquad::quadcontrol
