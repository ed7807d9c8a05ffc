// Options of the position controller and flight state machine, with the thesis defaults
// (Table 3.1 gains, 1.7 m hold height) and the reason for every other value. Loaded from the
// "controller" object of the quad-control JSON config
// (offboard/quadcontrol/config/quad-control.json); absent keys keep these defaults. is_valid()
// names the first bad field.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

#include "core/cascade_position.hpp"
#include "core/estimator_options.hpp"
#include "core/pid.hpp"

namespace rgbdquad::quadcontrol {

/// How roll/pitch follow the horizontal position (docs/control.md, "Position law").
enum class PositionLaw {
  kPid,      ///< the thesis: one PID per body axis, error in mm -> stick % (Table 3.1 gains)
  kCascade,  ///< position P -> velocity PI -> lean angle (core/cascade_position.hpp)
};
const char* to_string(PositionLaw law);

struct ControlConfig {
  // Table 3.1 (error in mm for roll/pitch/throttle, in degrees for yaw; output in percent of
  // stick). Output limits: +-20 % roll/pitch stick (~9 deg of tilt with ArduCopter's 45 deg
  // ANGLE_MAX) keeps an indoor craft slow; +-30 % yaw rate stick; +-30 % throttle around hover.
  PidGains roll{0.015, 0.0, 0.01, 20.0};
  PidGains pitch{0.015, 0.0, 0.01, 20.0};
  PidGains yaw{0.06, 0.0, 0.02, 30.0};
  PidGains throttle{0.025, 0.013, 0.02, 30.0};

  /// The default is the cascade: in the closed-loop model it holds the gusty hover to about half
  /// the thesis PID's error (docs/control.md); "pid" flies Table 3.1's structure with `roll` and
  /// `pitch` above.
  PositionLaw position_law = PositionLaw::kCascade;
  /// The cascade's gains (used when position_law is kCascade; its lean is limited by
  /// roll/pitch output_limit_pct as the PID's is).
  CascadeGains cascade;

  double hold_height_m = 1.7;        ///< thesis: hold at 1.7 m with no instruction
  double hover_throttle_pct = 50.0;  ///< feed-forward; the throttle integrator absorbs the rest
  double takeoff_climb_rate_m_per_s = 0.5;    ///< setpoint ramp: slow enough for a 30 Hz pose loop
  double takeoff_reached_tolerance_m = 0.1;   ///< within 10 cm of hold height -> hold
  double face_waypoint_tolerance_deg = 10.0;  ///< heading error below which the craft starts moving
  double waypoint_reached_m = 0.15;   ///< ~ the SLAM drift over a short flight; then hold there
  double turn_skip_distance_m = 0.3;  ///< closer goals are reached without turning
  double pose_timeout_ms = 300.0;     ///< 9 frames at 30 Hz without a tracked pose = lost
  double lost_hold_ms = 2000.0;       ///< neutral hover this long waiting for tracking, then land
  /// A pose estimate further than this from the last accepted one is rejected as a SLAM failure.
  /// Motion between two estimates is a few cm (1 m/s at 30 fps: 3 cm); measured in the HIL rig: a
  /// false loop closure jumped the estimate 1.5 m down to the take-off height and the height loop
  /// climbed at full throttle to 16 m. 0.5 m also passes a lost-hold's blind drift (~0.2 m in 2 s).
  double max_pose_jump_m = 0.5;
  /// A declared map correction (PoseSample::map_correction_count changed: SLAM corrected its
  /// trajectory, e.g. a loop closure) is accepted up to this size instead of max_pose_jump_m. The
  /// loop-off 10-minute HIL flight drifted to a 0.37 m waypoint error (docs/hil.md); 1.5 m is 4x
  /// that and still half the HIL room's 3 m: a larger "correction" is an aliased place, refused.
  double max_map_correction_m = 1.5;
  /// Tracked landing: the height setpoint sinks this fast (ArduCopter's LAND_SPEED is 0.5 m/s;
  /// 0.3 m/s leaves margin for ~80 ms of camera-to-motor latency at touchdown).
  double land_descent_rate_m_per_s = 0.3;
  double motor_stop_height_m = 0.15;     ///< camera height at which the motors are stopped
  double land_ground_settle_ms = 500.0;  ///< ... once the estimate has stayed there this long
  double land_floor_hold_ms =
      3000.0;  ///< tracked landing: stop this long after the setpoint reached the floor
  /// Blind landing (no pose): commands stop, the firmware's failsafe (250 ms) hands over to the
  /// APM's LAND at 0.5 m/s, which disarms ~1 s after touchdown: from 1.7 m ~5 s (measured 4.9 s
  /// in the HIL rig); 8 s leaves margin for 3 m. Then quad-control sends arm=0 (clears the latch).
  double failsafe_landing_ms = 8000.0;
  double manual_step_m = 0.1;             ///< one manual key press moves the setpoint 10 cm
  double manual_yaw_step_deg = 10.0;      ///< one manual key press turns the setpoint 10 deg
  double max_waypoint_distance_m = 10.0;  ///< a click further than this is a mistake, rejected
  // The flight envelope (core/flight_envelope.hpp): every setpoint, whatever API path set it, is
  // refused or clamped against these. Indoor defaults: the floor map is 10 m x 10 m around the
  // start (map.size_m), rooms are below 3 m; one manual key press is manual_step_m (0.1 m) /
  // manual_yaw_step_deg (10 deg), so a larger single step is not a key press and is refused.
  double max_distance_from_home_m = 5.0;  ///< horizontal radius around the take-off point
  double max_height_m = 3.0;       ///< height ceiling of every setpoint (hold_height_m below it)
  double max_manual_step_m = 1.0;  ///< one manual step per axis, at most (10 key presses)
  double max_manual_yaw_step_deg = 90.0;  ///< one manual turn, at most
  /// ArduCopter arms on throttle low + yaw full right held for 2 s, disarms on yaw full left for
  /// 2 s (docs/firmware.md); arming +1 s margin for pre-arm checks and the PWM frame delay;
  /// disarming +1.5 s: ArduCopter counts the 2 s only once its land detector says landed (~1 s at
  /// minimum output after touchdown; the HIL rig's APM stayed armed with a 2.5 s gesture).
  double arm_gesture_ms = 3000.0;
  double disarm_gesture_ms = 3500.0;
  /// The APM's roll/pitch/yaw stick dead zone (ArduCopter RC1_DZ/RC2_DZ/RC4_DZ, default 20 us):
  /// ArduPilot ignores the first 20 us off centre and rescales the rest. A non-zero stick is sent
  /// starting just outside it, so the APM's lean follows the PID output from 0 instead of ignoring
  /// it below 5 % of stick (at Table 3.1 gains a 0.33 m position dead band: measured in the HIL rig
  /// as a 0.7 m wander in 0.15 m/s^2 gusts). 0 = no compensation. Must match the APM's setting.
  double apm_stick_deadzone_us = 20.0;
  /// The APM's throttle dead band around hover_throttle_pct (ArduCopter AltHold's THR_DZ, default
  /// 100 us of 1000), stepped over the same way; 0 (default) for Stabilize, where throttle is
  /// thrust. With the APM in AltHold the height PID's output is a climb-rate command (use ki = 0:
  /// the APM holds the hover itself) and hover_throttle_pct must be 50 (mid-stick = no climb).
  double apm_throttle_deadband_us = 0.0;
  // Manoeuvres (FlightController::manoeuvre: a timed turn and/or straight move of the hold
  // setpoint at an asked rate, with the rate fed forward). Bounds on what a mission may ask; the
  // flight envelope still clamps every setpoint.
  /// 1.5 m/s: the camera bench scores SLAM on 1 m/s dashes (hil/tools/render_tum.py); at the
  /// 20 % lean limit (~9 deg) the craft's drag balances ~3 m/s, so 1.5 m/s leaves lean for control.
  double max_manoeuvre_speed_m_per_s = 1.5;
  /// 90 deg/s: below the firmware's hard yaw limit (+-250 us = 100 deg/s, firmware/core/limits.h);
  /// the camera bench scores SLAM on 60 and 120 deg/s turns.
  double max_manoeuvre_yaw_rate_deg_per_s = 90.0;
  /// Straight-line move of one manoeuvre, at most: half the default 5 m envelope radius.
  double max_manoeuvre_distance_m = 2.5;
  /// One manoeuvre's turn, at most: a full turn.
  double max_manoeuvre_turn_deg = 360.0;
  /// The setpoint's speed ramps up and down at this rate: 1.0 m/s^2 is two thirds of what the
  /// 20 % lean limit gives (g tan 9 deg = 1.55 m/s^2), leaving the rest to correct errors.
  double manoeuvre_accel_mss = 1.0;
  /// The heading setpoint's rate ramps at this: 60 deg/s is reached in 0.5 s (the camera bench's
  /// ramp, hil/tools/render_tum.py --ramp-s 0.5).
  double manoeuvre_yaw_accel_deg_per_s2 = 120.0;
  /// The APM's yaw rate at full stick (ArduCopter ACRO_YAW_P 4.5 x 45 deg/s): turns a turn rate
  /// into the yaw stick fed forward. Must match the APM (hil/fc_emulator: 202.5).
  double apm_yaw_rate_max_deg_per_s = 202.5;
  /// State estimation across pose gaps (IMU + delayed SLAM poses; docs/control.md "Estimator").
  EstimatorOptions estimator;

  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

/// Reads the fields present in `j` over `config`; returns an error text (empty on success) for a
/// wrong type or an unknown key, so typos are caught at start-up.
std::string load_control_config(const nlohmann::json& j, ControlConfig& config);
nlohmann::json to_json(const ControlConfig& config);

}  // namespace rgbdquad::quadcontrol
