// The flight state machine and position controller of quad-control (thesis Section 3.3.3).
//
//   disarmed -arm-> armed -takeoff-> take-off -(at hold height)-> hold <-waypoint/arrived-> go-to
//   take-off / hold / go-to -land-> land -(near the ground)-> disarmed;  armed -disarm-> disarmed
//   take-off / hold / go-to -(tracking lost)-> lost-hold -(tracking back)-> hold
//                                                       -(lost_hold_ms)-> land (blind)
//
// Position control: one PID per axis (roll: lateral error, pitch: forward error, throttle: height
// error, all in mm; yaw: heading error in degrees). Only yaw orients the craft and position never
// drives yaw: in hold the heading stays where take-off left it and a goal behind is reached by
// pitching backwards. A waypoint far enough away is approached by first turning to face it (roll
// and pitch hold the position meanwhile), then moving with the heading fixed.
// Landing is a steady throttle reduction; motors stop once the craft is close to the ground.
//
// Arming the APM: on entering armed the sticks hold ArduCopter's arming gesture (throttle 0, yaw
// full right) for arm_gesture_ms, and take-off waits for it; on entering disarmed from armed or
// from a landing they hold the disarm gesture (yaw full left) for disarm_gesture_ms with the
// firmware still armed, then release it (armed = false).
//
// Stick convention of StickCommand (percent of full deflection from neutral): roll_pct > 0 rolls
// right, pitch_pct > 0 pitches forward (nose down), yaw_pct > 0 turns clockwise seen from above
// (right stick); throttle_pct is absolute, 0..100. Conversion to the firmware's PWM units is
// stick_mapping.hpp's job.
//
// Flight envelope: every setpoint this class writes goes through FlightEnvelope (non-finite
// refused, distance from home and height clamped, waypoints outside refused); home is set at
// take-off. Manual steps larger than max_manual_step_m / max_manual_yaw_step_deg are refused.
//
// Time is passed in (monotonic microseconds, same clock for poses and update()). Not thread-safe:
// the app owns one instance behind a mutex.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/cascade_position.hpp"
#include "core/control_config.hpp"
#include "core/flight_envelope.hpp"
#include "core/pid.hpp"

namespace rgbdquad::quadcontrol {

enum class FlightState { kDisarmed, kArmed, kTakeOff, kHold, kGoToWaypoint, kLostHold, kLand };
const char* to_string(FlightState state);

enum class OperatorCommand { kArm, kDisarm, kTakeOff, kLand };
const char* to_string(OperatorCommand command);

/// Pose of the craft in the floor-aligned world frame (z = height above the floor).
struct CraftPose {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double yaw_deg = 0.0;  ///< counter-clockwise from world +x, seen from above
};

/// One pose estimate as it reached the controller.
struct PoseSample {
  std::int64_t received_us = 0;  ///< controller clock when the estimate arrived
  bool tracking = false;         ///< false: SLAM lost track, `pose` is meaningless
  CraftPose pose;
  /// SLAM's map-correction counter (PoseUpdate.map_correction_count): a change declares that a
  /// jump since the previous sample is a correction of the world-frame estimate, not motion.
  std::uint32_t map_correction_count = 0;
};

/// Floor-frame velocity (x, y, z), m/s.
using Velocity3 = std::array<double, 3>;

struct StickCommand {
  double roll_pct = 0.0;
  double pitch_pct = 0.0;
  double yaw_pct = 0.0;
  double throttle_pct = 0.0;
  bool armed = false;  ///< false: the firmware keeps its outputs at safe values
  /// Blind landing: send NO command. 250 ms later the firmware's failsafe puts the throttle below
  /// the APM's FS_THR_VALUE and the APM lands by itself (docs/failsafe.md).
  bool hand_over_to_failsafe = false;
};

struct Waypoint {
  double x_m = 0.0;
  double y_m = 0.0;
};

/// A timed move of the hold setpoint (a mission's fast turn or dash): the setpoint moves by
/// (forward_m, left_m) in the body frame of the heading setpoint at the start, at speed_m_per_s,
/// and turns by yaw_ccw_deg at yaw_rate_deg_per_s, both with ramped rates; the rates are fed
/// forward. Zero distance / turn needs no rate.
struct ManoeuvreRequest {
  double forward_m = 0.0;
  double left_m = 0.0;
  double yaw_ccw_deg = 0.0;
  double speed_m_per_s = 0.0;
  double yaw_rate_deg_per_s = 0.0;
};

/// What the controller is doing, for the dashboard and the tests.
struct ControllerStatus {
  FlightState state = FlightState::kDisarmed;
  bool facing_waypoint = false;  ///< go-to: false while turning, true while moving
  std::optional<Waypoint> waypoint;
  CraftPose setpoint;             ///< target x, y, z (z = height setpoint) and yaw
  bool manoeuvre_active = false;  ///< a ManoeuvreRequest is moving the hold setpoint
  std::uint64_t manoeuvres_done = 0;
  bool tracking = false;
  std::string last_event;  ///< human-readable reason of the last transition
  std::uint64_t rejected_poses =
      0;                         ///< estimates that jumped beyond max_pose_jump_m (SLAM failures)
  std::uint64_t map_resets = 0;  ///< declared map corrections accepted (re-anchored)
  std::uint64_t refused_map_corrections = 0;  ///< declared corrections beyond max_map_correction_m
};

class FlightController {
 public:
  /// `config` must be valid (ControlConfig::is_valid()); throws std::invalid_argument else.
  explicit FlightController(ControlConfig config);

  /// Operator buttons. Returns empty when accepted, else why not (state unchanged).
  std::string command(std::int64_t now_us, OperatorCommand command);
  /// Click on the map. Accepted in hold / go-to with tracking, inside the envelope and within
  /// max_waypoint_distance_m of the craft; replaces any previous waypoint.
  std::string set_waypoint(std::int64_t now_us, double x_m, double y_m);
  /// Manual keys: move the setpoint by the given steps (forward/left in the body frame). Steps must
  /// be finite and within max_manual_step_m / max_manual_yaw_step_deg; the moved setpoint is
  /// clamped into the envelope (last_event says so).
  std::string nudge(std::int64_t now_us, double forward_m, double left_m, double up_m,
                    double yaw_ccw_deg);

  /// A timed turn and/or straight move (ManoeuvreRequest). Accepted in hold with tracking and no
  /// manoeuvre in progress; finite values, the rate of each non-zero part > 0 and within
  /// max_manoeuvre_speed_m_per_s / max_manoeuvre_yaw_rate_deg_per_s, the move within
  /// max_manoeuvre_distance_m, the turn within max_manoeuvre_turn_deg, and the end point inside the
  /// flight envelope. The craft stays in hold; status().manoeuvre_active is true until the setpoint
  /// has arrived. A waypoint, manual step, landing or loss of tracking ends it where it is.
  std::string manoeuvre(std::int64_t now_us, const ManoeuvreRequest& request);

  /// Newest pose estimate. Non-finite poses count as tracking lost. `velocity_m_per_s`: when an
  /// estimator provides one (core/pose_estimator.hpp), the roll/pitch/throttle derivative terms
  /// use it instead of differencing poses (a non-finite one is ignored).
  void on_pose(const PoseSample& sample, std::optional<Velocity3> velocity_m_per_s = std::nullopt);

  /// One control step; call at the command rate (~50 Hz).
  StickCommand update(std::int64_t now_us);

  const ControllerStatus& status() const { return status_; }
  const ControlConfig& config() const { return config_; }
  const FlightEnvelope& envelope() const { return envelope_; }

 private:
  bool has_fresh_pose(std::int64_t now_us) const;
  // The steps of update(now_us), in order: the state changes tracking (or its loss) causes, then
  // the command of the state the craft is in.
  /// Takes-off, holds and goes-to-waypoint fall into LostHold without a fresh pose; LostHold
  /// resumes when tracking is back, or lands blind after lost_hold_ms.
  void supervise_tracking(std::int64_t now_us, bool fresh);
  /// Tracking back in LostHold: PIDs restarted, take-off climbs on, or hold (and the interrupted
  /// waypoint is taken up again).
  void resume_after_loss(std::int64_t now_us);
  StickCommand command_in_state(std::int64_t now_us, bool fresh);
  /// The climb ramp to hold_height_m; Hold once reached.
  StickCommand takeoff_step(std::int64_t now_us);
  /// Turn to face the waypoint, then fly to it; Hold once reached.
  StickCommand waypoint_step(std::int64_t now_us);
  /// Tracked: the sinking height setpoint; blind: the hand-over to the craft's failsafe.
  StickCommand land_step(std::int64_t now_us, bool fresh);
  /// Disarms (with the disarm gesture) once on the ground, or once the failsafe landing is over;
  /// else `cmd` unchanged.
  StickCommand land_touchdown(std::int64_t now_us, bool fresh, StickCommand cmd);
  void enter(FlightState state, std::int64_t now_us, const std::string& why);
  /// Moves the hold setpoint along the active manoeuvre's profile and sets the feed-forward.
  void advance_manoeuvre(std::int64_t now_us);
  void reset_pids();
  /// Roll/pitch/yaw/throttle from the PIDs, run once per pose sample (see the .cpp).
  StickCommand position_control(const PoseSample& sample, double height_setpoint_m);
  double unwrap_yaw(double yaw_deg);
  /// Writes the setpoint's position through the envelope; false (setpoint unchanged) when refused.
  /// `clamped` (optional) tells whether it was moved in.
  bool set_setpoint_position(double x_m, double y_m, double z_m, SetpointKind kind,
                             bool* clamped = nullptr);

  ControlConfig config_;
  FlightEnvelope envelope_;
  Pid roll_;
  Pid pitch_;
  Pid yaw_;
  Pid throttle_;
  CascadePosition cascade_;
  ControllerStatus status_;
  struct ActiveManoeuvre {
    std::int64_t start_us = 0;
    double x0_m = 0.0, y0_m = 0.0, yaw0_deg = 0.0;  ///< setpoint at the start
    double dir_x = 0.0, dir_y = 0.0;                ///< unit direction of the move (world)
    double distance_m = 0.0, turn_deg = 0.0;        ///< turn signed, ccw +
    double speed_m_per_s = 0.0, yaw_rate_deg_per_s = 0.0;
  };
  std::optional<ActiveManoeuvre> manoeuvre_;
  double ff_x_m_per_s_ = 0.0, ff_y_m_per_s_ = 0.0;  ///< setpoint velocity (world), fed forward
  double ff_yaw_deg_per_s_ = 0.0;                   ///< setpoint turn rate (ccw +), fed forward
  std::optional<PoseSample> pose_;
  std::optional<Velocity3> pose_velocity_;             ///< with pose_, when the estimator gave one
  std::optional<CraftPose> last_accepted_pose_;        ///< the jump gate's reference
  std::optional<std::uint32_t> map_correction_count_;  ///< the newest tracked sample's counter
  std::int64_t state_entered_us_ = 0;
  double takeoff_start_height_m_ = 0.0;
  double land_start_height_m_ = 0.0;  ///< tracked landing: the height the setpoint sinks from
  std::optional<std::int64_t> land_floor_reached_us_;
  std::optional<std::int64_t> handed_over_us_;  ///< blind landing: when commands stopped
  std::optional<std::int64_t> low_since_us_;    ///< tracked landing: first at motor-stop height
  double last_throttle_pct_ = 0.0;
  std::optional<double> unwrapped_yaw_deg_;
  double last_raw_yaw_deg_ = 0.0;
  bool disarm_gesture_pending_ = false;
  bool interrupted_takeoff_ = false;  ///< lost-hold was entered from take-off: resume it
  std::optional<Waypoint> interrupted_waypoint_;  ///< lost-hold was entered from go-to: resume it
  std::optional<std::int64_t> pid_pose_us_;       ///< received_us of the pose the PIDs last ran on
  StickCommand pid_cmd_;                          ///< their output, held until the next pose
};

}  // namespace rgbdquad::quadcontrol
