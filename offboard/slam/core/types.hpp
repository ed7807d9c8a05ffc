// Value types shared by every SLAM stage: camera intrinsics, one RGB-D frame, and pose helpers.
// Frames and poses cross stage boundaries by value; nothing here owns a thread or a device.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "rgbdquad/camera/tum_cameras.hpp"

namespace rgbdquad::slam {

/// Pinhole intrinsics of the colour camera (depth is registered to colour in TUM data). Defaults:
/// the TUM Freiburg 1 colour camera (protocol/camera/tum_cameras.json).
struct Intrinsics {
  double fx_px = rgbdquad::camera::kTumFr1.fx_px;
  double fy_px = rgbdquad::camera::kTumFr1.fy_px;
  double cx_px = rgbdquad::camera::kTumFr1.cx_px;
  double cy_px = rgbdquad::camera::kTumFr1.cy_px;
  /// OpenCV radial-tangential coefficients k1 k2 p1 p2 k3; used only when undistortion is on.
  std::array<double, 5> distortion = rgbdquad::camera::kTumFr1.distortion;
  /// Raw depth units per metre: TUM/Kinect PNGs store 5000 units = 1 m.
  double depth_units_per_m = rgbdquad::camera::kTumDepthUnitsPerM;

  bool is_valid(std::string* error) const;
  /// Named TUM cameras: "fr1", "fr2", "fr3", "ros_default" (protocol/camera/tum_cameras.json).
  static bool from_name(const std::string& name, Intrinsics* out, std::string* error);
};

/// Gravity's direction measured in a camera frame (unit vector) with its angular sigma; where it
/// comes from and how its sigma is set: slam/tracking/gravity_prior.hpp.
struct GravityObservation {
  Eigen::Vector3d down_cam = Eigen::Vector3d::UnitY();
  double sigma_rad = 1.0;
};

/// Whitened gravity residual of a camera whose world-to-camera rotation takes the world's gravity
/// direction to `predicted_down_cam` (R_cw d_w): (R_cw d_w - d_c) / sigma. Both are unit vectors,
/// so it constrains roll and pitch only; a turn about gravity or a move changes nothing. Shared by
/// the pose fit, local BA and the loop-closing pose graph (templated for Ceres' Jets).
template <typename T>
void gravity_residual(const T predicted_down_cam[3], const GravityObservation& g, T residual[3]) {
  const T inv_sigma = T(1.0 / g.sigma_rad);
  for (int i = 0; i < 3; ++i) residual[i] = (predicted_down_cam[i] - T(g.down_cam[i])) * inv_sigma;
}

/// One synchronised RGB-D frame. `rgb` is CV_8UC3 (BGR as loaded by OpenCV), `depth` CV_16UC1
/// in `Intrinsics::depth_units_per_m` units, 0 = no reading.
struct RgbdFrame {
  std::int64_t index = 0;  ///< position in the replayed/received stream
  double stamp_s = 0.0;    ///< capture time of the colour image
  cv::Mat rgb;
  cv::Mat depth;
  /// Camera attitude at `stamp_s` in a gravity-aligned navigation frame (the craft's IMU attitude
  /// times the camera mount), when the caller has one. The tracker uses only its change between
  /// consecutive frames, so the navigation frame need not be the map's.
  std::optional<Eigen::Quaterniond> q_nav_cam;
  /// Capture time of the depth image when it differs from `stamp_s` (the Kinect's colour and depth
  /// run on separate clocks); the tracker re-times the depth to `stamp_s` while the camera turns
  /// (slam/tracking/depth_time_alignment.hpp).
  std::optional<double> depth_stamp_s;
  /// The Kinect's accelerometer sample nearest the colour image's capture time, as the specific
  /// force it measures (acceleration minus gravity: at rest it points UP, magnitude ~9.81 m/s^2),
  /// in m/s^2, expressed in the colour camera's optical frame (x right, y down, z along the
  /// optical axis; rotated from the sensor's axes with rgbdquad::camera::kKinectV1Accelerometer).
  /// Set only when the sample passed slam::AccelGate (slam/motion/accel_gate.hpp): finite, within
  /// the gate's stamp bound of the colour stamp, unsaturated, of plausible magnitude.
  std::optional<Eigen::Vector3d> accel_cam_mps2;
  /// Capture time of that sample, seconds on the same clock as `stamp_s`; set with accel_cam_mps2.
  std::optional<double> accel_stamp_s;
};

/// What a tracker knows of the camera's pose after a frame.
enum class TrackingState { kInitialising, kTracking, kLost };
const char* to_string(TrackingState s);

/// Milliseconds elapsed on a steady clock since `start_ns` (instrumentation only, never logic).
std::int64_t steady_now_ns();
/// CPU time consumed by the calling thread, nanoseconds (instrumentation only).
std::int64_t thread_cpu_now_ns();
/// A capture stamp in microseconds (the stream's and the SLAM link's) as SLAM's seconds. Divided,
/// not multiplied by 1e-6: the quotient is the double nearest the exact value, the one a TUM
/// folder's 6-decimal stamp reads back as, so a replayed flight gives SLAM the very same stamps.
inline double seconds_from_us(std::int64_t us) { return static_cast<double>(us) / 1e6; }

inline double ms_since(std::int64_t start_ns) { return (steady_now_ns() - start_ns) * 1e-6; }

/// The cross-product matrix of v: skew(v) w = v x w.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

/// Rotation angle of a rigid transform in radians.
inline double rotation_angle_rad(const Eigen::Isometry3d& T) {
  return Eigen::AngleAxisd(T.rotation()).angle();
}

/// True when every element of the transform is finite.
inline bool is_finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

}  // namespace rgbdquad::slam
