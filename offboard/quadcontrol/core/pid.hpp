// One PID controller for one axis of the position loop (thesis Section 3.3.3, Table 3.1).
//
// Contract: update(now_us, setpoint, measurement) returns the clamped output, or std::nullopt when
// an input is non-finite or time did not move forward (the state is then left unchanged, so one bad
// sample never poisons the integrator). Derivative acts on the measurement (no kick when the
// setpoint jumps, e.g. a new waypoint). Anti-windup: the integrator is frozen only while the output
// is saturated AND the error would drive it further into saturation (ArduPilot AC_PID style).
// Time is passed in; nothing here reads a clock. Not thread-safe: one owner per instance.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace rgbdquad::quadcontrol {

/// Gains and limit of one axis. Units: error in the axis' unit (mm or deg), output in percent of
/// stick deflection (see docs/control.md). Defaults are zero; Table 3.1 values live in
/// ControlConfig.
struct PidGains {
  double kp = 0.0;
  double ki = 0.0;                ///< per second
  double kd = 0.0;                ///< seconds
  double output_limit_pct = 0.0;  ///< |output| <= this
  /// True when the gains are finite and >= 0 and the limit finite and > 0; else false and, if
  /// error is not null, the reason.
  bool is_valid(std::string* error) const;
};

/// Contributions of the last accepted update (for the dashboard and tests).
struct PidTerms {
  double p = 0.0;
  double i = 0.0;
  double d = 0.0;
  double output = 0.0;
  bool saturated = false;
};

class Pid {
 public:
  explicit Pid(PidGains gains) : gains_(gains) {}

  /// One control step at `now_us` (monotonic, microseconds). error = setpoint - measurement.
  /// `measurement_rate_per_s`: the measurement's rate of change (unit per second) when the caller
  /// has an estimate of it (quad-control's IMU-aided velocity); the derivative term then uses it
  /// instead of differencing successive measurements. A non-finite rate is rejected like a
  /// non-finite measurement.
  std::optional<double> update(std::int64_t now_us, double setpoint, double measurement,
                               std::optional<double> measurement_rate_per_s = std::nullopt);

  /// Forget integrator and derivative history (e.g. on a mode change).
  void reset();
  /// Forget only the derivative history (after a gap in the measurements, e.g. tracking lost and
  /// back): the integrator keeps what it learned (the hover throttle offset).
  void restart();

  const PidTerms& last_terms() const { return terms_; }
  double integral() const { return integral_; }
  const PidGains& gains() const { return gains_; }

 private:
  PidGains gains_;
  double integral_ = 0.0;  ///< integral term, already multiplied by ki (output units)
  std::optional<double> last_measurement_;
  std::optional<std::int64_t> last_time_us_;
  PidTerms terms_;
};

}  // namespace rgbdquad::quadcontrol
