// Accelerometer gate: decides whether the Kinect's accelerometer sample for one frame is usable as
// a measurement of gravity's direction (roll/pitch prior, gravity factor), and puts the accepted
// sample into the frame in the colour camera's optical frame.
//
// A sample is refused, with the reason counted, when it is missing, not finite, stale (its stamp
// further than max_stamp_gap_s from the colour stamp), saturated (an axis at the sensor's
// measuring range, so the reading is clipped and its direction wrong) or of implausible magnitude
// (the motion's own acceleration is too large a part of it for its direction to be gravity's).
// The checks run on the raw sample in the sensor's own axes, where the range applies per axis.
//
// Time is a parameter: the gate never reads a clock. Thread safety: one gate per frame stream;
// check() and attach() mutate the counters, so calls on one gate must not overlap.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <optional>
#include <string>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "slam/core/types.hpp"

namespace rgbdquad::slam {

/// The Kinect v1 accelerometer's per-axis measuring range, m/s^2 (+-2 g at libfreenect's g:
/// protocol/camera/tum_cameras.json, "accelerometer"). A reading at or beyond it is clipped.
inline constexpr double kKinectAccelRangeMps2 =
    rgbdquad::camera::kKinectV1Accelerometer.range_mps2();
/// Standard gravity, m/s^2, the g the Kinect's driver scales its counts with.
inline constexpr double kStandardGravityMps2 =
    rgbdquad::camera::kKinectV1Accelerometer.standard_gravity_mps2;
/// Largest gap between the sample's stamp and the colour stamp, seconds: the TUM benchmark's own
/// association rule (20 ms, as rgb/depth pairing). The sensor samples at ~860 Hz in TUM's
/// recordings (1.16 ms median spacing), and the streamer reads it once per colour frame, so a
/// fresh sample is always far closer; one older than 20 ms belongs to a different frame's motion.
inline constexpr double kAccelMaxStampGapS = 0.02;
/// Accepted specific-force magnitude, m/s^2: 1 g +- 0.5 g. Beyond that the motion's acceleration
/// is at least half of gravity, so the sample's direction can be up to 30 degrees off gravity's
/// (asin 0.5) and is no use as a roll/pitch measurement. The hand-held fr1 recordings stay inside
/// (0.79 g .. 1.33 g over fr1_xyz and fr1_360); a hovering craft reads ~1 g.
inline constexpr double kAccelMinMagnitudeMps2 = 0.5 * kStandardGravityMps2;
inline constexpr double kAccelMaxMagnitudeMps2 = 1.5 * kStandardGravityMps2;

/// One raw accelerometer reading as the sensor delivers it: specific force in the sensor's axes
/// (for the Kinect v1, libfreenect's freenect_get_mks_accel / TUM accelerometer.txt), m/s^2.
struct AccelSample {
  double stamp_s = 0.0;  ///< capture time, same clock as RgbdFrame::stamp_s
  Eigen::Vector3d f_sensor_mps2 = Eigen::Vector3d::Zero();
};

/// Why a sample was or was not used. kAccepted first; the rest in the order they are checked.
enum class AccelVerdict { kAccepted, kMissing, kNonFinite, kStale, kSaturated, kImplausible };
inline constexpr std::size_t kAccelVerdictCount = 6;
/// "accepted", "missing", "non_finite", "stale", "saturated", "implausible_magnitude".
const char* to_string(AccelVerdict v);

struct AccelGateOptions {
  double max_stamp_gap_s = kAccelMaxStampGapS;
  double range_mps2 = kKinectAccelRangeMps2;  ///< per-axis measuring range, m/s^2
  double min_magnitude_mps2 = kAccelMinMagnitudeMps2;
  double max_magnitude_mps2 = kAccelMaxMagnitudeMps2;
  /// Row-major rotation from the sensor's axes to the colour camera's optical frame.
  std::array<double, 9> R_cam_sensor = rgbdquad::camera::kKinectV1Accelerometer.R_cam_accel;
  /// False when a bound is not finite/positive, min >= max magnitude, or R_cam_sensor is not a
  /// rotation (orthonormal within 1e-9, determinant +1).
  bool is_valid(std::string* error) const;
};

/// Samples seen per verdict since construction.
struct AccelCounts {
  std::array<std::size_t, kAccelVerdictCount> by_verdict{};
  std::size_t of(AccelVerdict v) const { return by_verdict[static_cast<std::size_t>(v)]; }
  std::size_t accepted() const { return of(AccelVerdict::kAccepted); }
  std::size_t ignored() const;  ///< every verdict but kAccepted
  std::size_t total() const { return accepted() + ignored(); }
};

class AccelGate {
 public:
  /// Options must be valid (AccelGateOptions::is_valid); invalid ones are replaced by the defaults
  /// and reported by options_error().
  explicit AccelGate(const AccelGateOptions& options = {});

  /// The verdict on `sample` for the frame whose colour image was captured at colour_stamp_s
  /// (seconds); counts it.
  AccelVerdict check(double colour_stamp_s, const std::optional<AccelSample>& sample);

  /// check(), then on kAccepted sets frame->accel_cam_mps2 (the sample rotated into the optical
  /// frame) and frame->accel_stamp_s; otherwise clears both.
  AccelVerdict attach(double colour_stamp_s, const std::optional<AccelSample>& sample,
                      RgbdFrame* frame);

  /// The sample's specific force in the colour camera's optical frame.
  Eigen::Vector3d to_camera(const Eigen::Vector3d& f_sensor_mps2) const;

  const AccelCounts& counts() const { return counts_; }
  const AccelGateOptions& options() const { return options_; }
  /// Empty when the options passed to the constructor were valid.
  const std::string& options_error() const { return options_error_; }

 private:
  AccelVerdict judge(double colour_stamp_s, const std::optional<AccelSample>& sample) const;

  AccelGateOptions options_;
  Eigen::Matrix3d R_cam_sensor_;
  AccelCounts counts_;
  std::string options_error_;
};

}  // namespace rgbdquad::slam
