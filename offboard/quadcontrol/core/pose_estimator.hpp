// State estimation across pose gaps: fuses the SLAM poses (stamped at camera capture, arriving
// 30-400 ms later) with the APM's IMU read back over the firmware link (MAVLink RAW_IMU specific
// force + ATTITUDE angles, carried by every control reply), so the controller acts on an estimate
// of where the craft is NOW, with a velocity from the accelerometer, instead of on a pose that is
// 200-400 ms old after a stream stall (HIL scenario 5).
//
// Design (how flight stacks fuse delayed external vision; no code taken from them):
//  * PX4 EKF2 and ArduPilot EKF3 run their filter on a delayed "fusion time horizon" (the oldest
//    sensor delay, EKF2_EV_DELAY) and carry it forward to the present with buffered IMU samples in
//    an output predictor. They do so because replaying a 24-state EKF is too costly on a flight
//    controller. Our state is 3 x 3 numbers and the history is <= 1 s of 25 Hz samples, so this
//    class keeps a time-ordered event history (IMU inputs and poses) and, when a pose arrives,
//    inserts it at its capture time and replays the filter from there to the newest IMU sample:
//    exact for this linear filter, and an out-of-order (older) pose is simply inserted further
//    back.
//  * Per axis of the floor frame (x, y, z up) a linear Kalman filter with state [position,
//    velocity, accelerometer bias]: the IMU's world acceleration is the input of the prediction,
//    the SLAM position the measurement. The bias state absorbs the level-calibration error of the
//    APM (a 0.5 deg trim error reads as 0.086 m/s^2 of horizontal acceleration).
//  * The accelerometer is rotated into the floor frame with the APM's roll/pitch and the heading
//    offset between the APM's yaw and the SLAM yaw, measured at every fused pose (so an indoor
//    compass offset does not matter, only the APM yaw's change over < 1 s).
//  * Bounded extrapolation: an estimate is valid only while its newest fused pose was captured at
//    most `max_prediction_ms` ago and its position sigma is at most `max_position_sigma_m`. Beyond
//    that the caller must treat tracking as lost (quad-control's lost-hold -> blind landing takes
//    over, as without the estimator); the estimator never extrapolates indefinitely.
//  * Poses whose innovation exceeds `max_innovation_m` are rejected (a SLAM failure, e.g. a false
//    loop closure), as the controller's jump gate does for raw poses.
//
// Frames and units: floor frame z up, yaw counter-clockwise from +x in degrees (as CraftPose);
// IMU body frame FRD, APM angles NED / ZYX Euler (as MAVLink ATTITUDE). Times are monotonic
// microseconds of the caller's clock, passed in: nothing here reads a clock.
// Not thread-safe: the owner (quad-control's ground station) guards it.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <deque>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>

#include "core/estimator_options.hpp"
#include "core/flight_controller.hpp"
#include "link/control_codec.hpp"

namespace rgbdquad::quadcontrol {

/// One IMU reading of the APM as the ground station received it.
struct ImuSample {
  std::int64_t t_us = 0;  ///< when the APM sampled it, caller's clock
  Eigen::Vector3d specific_force_frd_mss{0, 0,
                                         0};  ///< accelerometer, body FRD (level at rest: 0, 0, -g)
  double roll_rad = 0.0, pitch_rad = 0.0, yaw_rad = 0.0;  ///< APM ATTITUDE, NED, ZYX Euler
  /// When the ATTITUDE part was sampled, caller's clock (`t_us` is the newer of ATTITUDE and
  /// RAW_IMU, which stream at different rates); nullopt: take `t_us`.
  std::optional<std::int64_t> attitude_t_us;
};

/// The IMU content of a control reply (RAW_IMU in mg, ATTITUDE in mrad, ages in ms), stamped with
/// the reply's arrival minus the newer of the two ages, and the attitude with its own age (the
/// reply's transit back, ~2-5 ms, is not subtracted). nullopt when the reply carries no IMU or no
/// attitude yet.
std::optional<ImuSample> imu_sample_from_reply(const rgbd_control::Reply& reply,
                                               std::int64_t received_us);

/// Maps the camera's capture stamps (the craft's clock, not synchronised with the ground
/// station's) to the ground station's clock: capture + the smallest (received - capture) over the
/// last `window` frames, i.e. the clock offset plus the fastest transit seen (the minimum-delay
/// rule of one-way clock synchronisation; a sliding window so crystal drift, ~50 ppm, is followed).
/// On one machine (the HIL rig) the offset is the fastest transit, 1-5 ms.
class CaptureClock {
 public:
  /// 300 frames = 10 s at 30 fps: long enough to contain a frame that crossed an idle link, short
  /// enough that 50 ppm of drift stays below 0.5 ms.
  explicit CaptureClock(std::size_t window = 300) : window_(window == 0 ? 1 : window) {}
  /// Records one frame and returns its capture time on the ground station's clock.
  std::int64_t to_local(std::int64_t capture_us, std::int64_t received_us);
  /// The same conversion with the offset of the frames recorded so far, recording nothing (for a
  /// frame that is recorded later); nullopt before the first frame.
  std::optional<std::int64_t> peek(std::int64_t capture_us) const;

 private:
  std::size_t window_;
  std::deque<std::int64_t> offsets_us_;
};

enum class FuseOutcome { kFused, kInitialised, kRejectedJump, kTooOld, kNonFinite };
const char* to_string(FuseOutcome outcome);

/// The estimate at one instant.
struct StateEstimate {
  bool valid = false;       ///< false: do not fly on it (no pose yet, too old or too uncertain)
  std::string why_invalid;  ///< empty when valid
  CraftPose pose;           ///< position and heading now
  Eigen::Vector3d velocity_m_per_s{0, 0, 0};  ///< floor frame
  Eigen::Vector3d position_sigma_m{0, 0, 0};  ///< 1 sigma per axis
  double age_ms = 0.0;                        ///< since the capture of the newest fused pose
  bool imu_aided = false;                     ///< the prediction to now used a fresh IMU input
};

struct EstimatorStats {
  std::uint64_t imu_samples = 0,
                imu_dropped = 0;  ///< dropped: duplicate, out of order or non-finite
  std::uint64_t poses_fused = 0, poses_out_of_order = 0, poses_rejected = 0, poses_too_old = 0;
  std::uint64_t resets = 0;        ///< re-initialised on a pose after the estimate had expired
  std::uint64_t frame_shifts = 0;  ///< declared map corrections applied (shift_frame)
};

class PoseEstimator {
 public:
  /// `options` must be valid (is_valid()); throws std::invalid_argument otherwise.
  explicit PoseEstimator(EstimatorOptions options);

  /// An IMU sample (time order; a duplicate of the newest, an older or a non-finite one is
  /// dropped, returns false).
  bool predict(const ImuSample& sample);
  /// A SLAM pose captured at `capture_us` (may be older than IMU samples already seen, and older
  /// than poses already fused).
  FuseOutcome fuse_pose(const CraftPose& pose, std::int64_t capture_us);
  /// The estimate at `now_us` (predicted from the newest state; does not change the filter).
  StateEstimate estimate(std::int64_t now_us) const;
  /// Forget everything (e.g. a new SLAM world frame).
  void reset();
  /// A declared map correction (SLAM moved its estimate of the trajectory by `delta`, e.g. a loop
  /// correction; PX4 EKF2's local-position reset): every position in the history (posteriors and
  /// the pose measurements replays fuse) is shifted by `delta`, velocity, bias and covariances are
  /// kept, so the next pose in the corrected frame passes the innovation gate. False (nothing
  /// changed) before the first pose or with a non-finite delta.
  bool shift_frame(const Eigen::Vector3d& delta_m);

  const EstimatorStats& stats() const { return stats_; }
  const EstimatorOptions& options() const { return options_; }

 private:
  /// Kalman state of one floor axis: [position m, velocity m/s, accelerometer bias m/s^2].
  struct Axis {
    Eigen::Vector3d x{0, 0, 0};
    Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  };
  using State = std::array<Axis, 3>;
  /// The IMU reading in the level (heading-aligned) frame: forward, left, up acceleration, m/s^2.
  struct LevelInput {
    std::int64_t t_us = 0;
    Eigen::Vector3d accel_flu_mss{0, 0, 0};
    double apm_yaw_rad = 0.0;
  };
  struct Event {
    std::int64_t t_us = 0;
    std::optional<LevelInput> imu;    ///< an IMU sample (becomes the input from t_us on)
    std::optional<CraftPose> pose;    ///< a pose measurement captured at t_us
    State posterior;                  ///< filter state right after this event
    std::optional<LevelInput> input;  ///< the IMU input in effect after this event
  };

  void predict_axis(Axis& a, double dt_s, double accel_mss, double noise_density) const;
  /// Advances `s` from `from_us` to `to_us` with `input` (held constant, zero if stale/absent).
  void propagate(State& s, std::int64_t from_us, std::int64_t to_us,
                 const std::optional<LevelInput>& input) const;
  Eigen::Vector3d floor_accel(const LevelInput& input) const;
  bool input_fresh(const std::optional<LevelInput>& input, std::int64_t t_us) const;
  /// Replays events [from, end) starting from the posterior of event from-1.
  void replay_from(std::size_t from);
  void trim_history();

  EstimatorOptions options_;
  EstimatorStats stats_;
  std::deque<Event> history_;
  std::optional<LevelInput> pending_input_;  ///< newest IMU input before the first pose
  std::optional<CraftPose> newest_pose_;     ///< the fused pose with the newest capture stamp
  std::int64_t newest_pose_capture_us_ = 0;
  std::optional<ImuSample> last_imu_raw_;  ///< the newest IMU sample accepted (order check)
  std::optional<double> yaw_offset_rad_;  ///< SLAM yaw (ccw) + APM yaw (cw, NED) at the newest pose
};

}  // namespace rgbdquad::quadcontrol
