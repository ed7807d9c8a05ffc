// Per-axis PID: see pid.hpp for the contract.
#include "core/pid.hpp"

#include <algorithm>
#include <cmath>

#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kMicrosecondsPerSecond = 1e6;
}  // namespace

bool PidGains::is_valid(std::string* error) const {
  for (double g : {kp, ki, kd}) {
    if (!std::isfinite(g) || g < 0.0) return reject(error, "PID gains must be finite and >= 0");
  }
  if (!std::isfinite(output_limit_pct) || output_limit_pct <= 0.0) {
    return reject(error, "PID output_limit_pct must be finite and > 0");
  }
  return true;
}

void Pid::restart() {
  last_measurement_.reset();
  last_time_us_.reset();
}

void Pid::reset() {
  integral_ = 0.0;
  last_measurement_.reset();
  last_time_us_.reset();
  terms_ = PidTerms{};
}

std::optional<double> Pid::update(std::int64_t now_us, double setpoint, double measurement,
                                  std::optional<double> measurement_rate_per_s) {
  if (!std::isfinite(setpoint) || !std::isfinite(measurement)) return std::nullopt;
  if (measurement_rate_per_s && !std::isfinite(*measurement_rate_per_s)) return std::nullopt;
  if (last_time_us_ && now_us <= *last_time_us_) return std::nullopt;

  const double error = setpoint - measurement;
  const double limit = gains_.output_limit_pct;
  double dt_s = 0.0;
  double d_term = 0.0;
  if (last_time_us_) {
    dt_s = static_cast<double>(now_us - *last_time_us_) / kMicrosecondsPerSecond;
    // Derivative on measurement: -kd * d(measurement)/dt, so a setpoint step gives no kick.
    d_term = -gains_.kd * (measurement - *last_measurement_) / dt_s;
  }
  if (measurement_rate_per_s) d_term = -gains_.kd * *measurement_rate_per_s;
  const double p_term = gains_.kp * error;

  // Anti-windup: integrate unless the output is saturated and the error pushes further out.
  const double candidate_integral = integral_ + gains_.ki * error * dt_s;
  const double unclamped = p_term + candidate_integral + d_term;
  const bool pushes_high = unclamped > limit && error > 0.0;
  const bool pushes_low = unclamped < -limit && error < 0.0;
  if (!pushes_high && !pushes_low) integral_ = std::clamp(candidate_integral, -limit, limit);

  const double raw = p_term + integral_ + d_term;
  const double output = std::clamp(raw, -limit, limit);
  terms_ = PidTerms{p_term, integral_, d_term, output, raw != output};
  last_measurement_ = measurement;
  last_time_us_ = now_us;
  return output;
}

}  // namespace rgbdquad::quadcontrol
