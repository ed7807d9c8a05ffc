// The cascaded horizontal position law (controller.position_law "cascade", the default): position
// error -> velocity setpoint (P, plus the trajectory's velocity feed-forward) -> acceleration (PI
// on the velocity error) -> lean angle (atan(a / g)) -> roll/pitch stick through the APM's
// ANGLE_MAX. The structure of ArduCopter's AC_PosControl, in physical units (1/s, 1/s^2) instead of
// the thesis PID's percent of stick per mm.
//
// Why it replaces the thesis PID as the default (docs/control.md, "Position law"): the thesis law
// is a PD on position with no integral, so the APM's level-trim error leaves a constant offset and
// the low-frequency part of the gusts (2 s correlation, below the loop's ~1.7 rad/s) is resisted by
// stiffness alone; its derivative term is the velocity, so it has no place for a trajectory's
// velocity and a moving setpoint trails it by v * kd / kp (1 m at 1 m/s). Here the velocity
// integral takes out the trim and most of the gust energy below ~0.5 rad/s, and a dash's velocity
// enters as feed-forward.
//
// Frames: everything is in the craft's body frame (forward, left), because the persistent
// disturbance the integral learns is the APM's level error, which turns with the craft; the gusts
// decorrelate within seconds.
//
// Contract: update() returns the lean command as stick percent, or std::nullopt when an input is
// non-finite or time did not move forward (state unchanged). Without a measured velocity it
// differences successive positions (as the thesis PID's derivative does). Anti-windup: an axis'
// integrator is frozen while that axis' output is clamped and the velocity error pushes further
// out. Time is passed in; nothing reads a clock. Not thread-safe: one owner.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace rgbdquad::quadcontrol {

struct CascadeGains {
  /// Position error -> velocity setpoint. 1/s: a 0.1 m error asks for 0.1 m/s back.
  double position_kp_per_s = 1.0;
  /// Velocity error -> acceleration. The HIL rig's thesis-law kd 0.04 %/(mm/s) is 3.1/s in these
  /// units (0.04 % x 1000 mm x 0.45 deg/% = 0.31 rad per m/s, x g); 3.5/s with position_kp 1/s
  /// places the loop at ~1.9 rad/s with 0.94 damping, and in the closed-loop model it stays stable
  /// with 70 ms more delay and a 30 % slower attitude loop (docs/control.md, "Position law").
  double velocity_kp_per_s = 3.5;
  /// Integral of the velocity error -> acceleration. 1/s^2; its zero (ki / kp = 0.29 rad/s) sits
  /// 6x below the loop's crossover, so it costs ~9 deg of phase; a higher ki (1.5) lost stability
  /// in the model's slow case.
  double velocity_ki_per_s2 = 1.0;
  /// The integrator's share of the acceleration, at most: 1.0 m/s^2 is ~6 deg of lean, six times
  /// the 0.5 deg trim error the rig flies with, so a wound-up integrator cannot lean the craft far.
  double integral_limit_mss = 1.0;
  /// The position loop's own velocity setpoint, at most (feed-forward comes on top): a waypoint
  /// step of 2 m is flown at 0.5 m/s, the thesis craft's indoor pace, not at 2 m/s.
  double max_correction_speed_m_per_s = 0.5;
  /// The APM's ANGLE_MAX (ArduCopter default 45 deg): full stick deflection is this lean.
  double angle_max_deg = 45.0;

  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

/// Body-frame horizontal quantities (m, m/s or m/s^2): forward along the heading, left 90 deg ccw.
struct BodyVector {
  double forward = 0.0;
  double left = 0.0;
};

/// What the law did on the last accepted update (the dashboard and tests).
struct CascadeTerms {
  BodyVector velocity_setpoint_m_per_s;
  BodyVector velocity_m_per_s;  ///< measured (estimator) or differenced
  BodyVector integral_mss;      ///< the integrator's acceleration
  BodyVector acceleration_mss;  ///< commanded, before the lean limit
  BodyVector stick_pct;         ///< forward = pitch stick (+ nose down), left = -roll stick
  bool saturated = false;
};

class CascadePosition {
 public:
  /// `gains` must be valid; `lean_limit_pct`: roll/pitch stick limit (ControlConfig roll/pitch
  /// output_limit_pct). Throws std::invalid_argument otherwise.
  CascadePosition(CascadeGains gains, double lean_limit_pct);

  /// One step at `now_us`. `position_error_m`: setpoint - craft, body frame. `velocity_m_per_s`:
  /// the craft's velocity (body frame) when an estimator has one. `feed_forward_m_per_s`: the
  /// setpoint's own velocity (a manoeuvre), body frame. Returns the stick (forward = pitch %,
  /// left = -roll %), each within +-lean_limit_pct.
  std::optional<BodyVector> update(std::int64_t now_us, BodyVector position_error_m,
                                   std::optional<BodyVector> velocity_m_per_s = std::nullopt,
                                   BodyVector feed_forward_m_per_s = {});

  /// Forget the integrator and the differencing history (disarmed, take-off).
  void reset();
  /// Forget only the differencing history (a gap in the poses, a map correction).
  void restart();

  const CascadeTerms& last_terms() const { return terms_; }
  const CascadeGains& gains() const { return gains_; }

 private:
  CascadeGains gains_;
  double lean_limit_pct_;
  BodyVector integral_mss_;
  std::optional<BodyVector> last_error_m_;
  std::optional<std::int64_t> last_time_us_;
  CascadeTerms terms_;
};

}  // namespace rgbdquad::quadcontrol
