// Options of quad-control's state estimator (core/pose_estimator.hpp), loaded from the
// "estimator" object inside "controller" of the quad-control JSON config. Separate from
// pose_estimator.hpp so ControlConfig can hold them without including the estimator.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

namespace rgbdquad::quadcontrol {

/// Options of the estimator (config: "controller": {"estimator": {...}}); every default has its
/// reason in the comment.
struct EstimatorOptions {
  /// Off: the controller flies on the raw SLAM poses, stamped at their arrival (the design before
  /// 2 Dec 2026). Measured in the HIL rig with and without: docs/control.md.
  bool enabled = true;
  /// The longest a pose may be extrapolated with the IMU. The worst pose gap measured in HIL
  /// scenario 5 (2 % loss -> 200 ms TCP retransmission stalls, bursts, ~100 ms of SLAM) is
  /// 400 ms; 500 ms covers it. With the residual accelerometer error after bias estimation
  /// (~0.1 m/s^2) and a 0.05 m/s velocity error that is <= ~4 cm of drift, a quarter of the
  /// 0.15 m hold tolerance. Without IMU samples the sigma limit below ends it sooner.
  double max_prediction_ms = 500.0;
  /// An estimate less certain than this (1 sigma, horizontal) is not flown on: two thirds of the
  /// 0.15 m hold tolerance.
  double max_position_sigma_m = 0.10;
  /// Poses further than this from the predicted position are rejected as SLAM failures: the
  /// controller's max_pose_jump_m (0.5 m, a false loop closure jumped 1.5 m in the HIL rig).
  double max_innovation_m = 0.5;
  /// SLAM position noise (1 sigma per axis): the local-map SLAM's ATE in the HIL hover is 4-9 mm;
  /// 10 mm also covers the capture-stamp jitter at 0.3 m/s (~1 ms).
  double pose_sigma_m = 0.01;
  /// Acceleration error of the IMU input as white noise, density in (m/s^2)/sqrt(Hz): RAW_IMU's
  /// 8 mg sensor noise at 10 Hz (0.08 m/s^2 x sqrt(0.1 s) = 0.025) and the tilt change between
  /// 25 Hz ATTITUDE samples held constant (a 5 deg lean change in 0.2 s is ~0.2 m/s^2 per 40 ms
  /// sample: 0.2 x sqrt(0.04 s) = 0.04); 0.1 is twice their sum. Constant errors (level trim) are
  /// the bias state's.
  double imu_accel_noise_mss_per_sqrt_hz = 0.1;
  /// Without IMU input (none yet, or older than imu_timeout_ms) the craft's own acceleration is
  /// unknown: +-20 % roll/pitch stick is ~9 deg of lean, 1.5 m/s^2, changing over ~1 s.
  double no_imu_accel_noise_mss_per_sqrt_hz = 1.5;
  /// Random walk of the accelerometer bias (the APM's level error seen in the floor frame changes
  /// as the craft yaws): 0.02 m/s^2 per sqrt(s).
  double bias_walk_mss_per_sqrt_s = 0.02;
  /// Initial uncertainty of velocity (a hand-held or hovering craft, < 0.5 m/s) and bias (a
  /// level error up to ~1.2 deg, 0.2 m/s^2).
  double initial_velocity_sigma_m_per_s = 0.5;
  double initial_bias_sigma_mss = 0.2;
  /// An IMU input older than this is not used (RAW_IMU at 10 Hz, ATTITUDE at 25 Hz: 3 RAW_IMU
  /// periods missed means the telemetry stopped).
  double imu_timeout_ms = 300.0;
  /// How far back the event history reaches: longer than max_prediction_ms plus the 400 ms worst
  /// pose delay, so a delayed pose still finds the IMU samples since its capture.
  double history_ms = 1500.0;
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

/// Reads the fields present in `j` over `options` (unknown key or wrong type -> the error text).
std::string load_estimator_options(const nlohmann::json& j, EstimatorOptions& options);
nlohmann::json to_json(const EstimatorOptions& options);

}  // namespace rgbdquad::quadcontrol
