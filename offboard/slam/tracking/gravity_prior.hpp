// Gravity as a roll/pitch prior in pose tracking. Vision alone leaves the map's attitude free to
// drift about horizontal axes (a slow tilt the ground truth shows in HIL flights before the first
// loop correction); the direction of gravity, measured in the camera frame, makes roll and pitch
// observable while yaw and position stay free.
//
// Sources, per frame (RgbdFrame):
//  - `q_nav_cam`, the craft's attitude from its flight controller. Its navigation frame is NED (the
//    APM's, protocol CameraAttitude), so gravity points along +z there. The APM's attitude
//    estimate is filtered over its gyros and accelerometers: sigma 1 deg (ArduPilot's EKF reports
//    tilt errors below a degree in hover; a degree leaves room for the camera mount).
//  - `accel_cam_mps2`, the Kinect's accelerometer (specific force, at rest pointing up): gravity
//    is its opposite direction. The sensor measures the motion's acceleration too, so its sigma is
//    a base of 3 deg (a hand-held or flying camera's lateral acceleration of 0.5 m/s^2 tilts it by
//    asin(0.5 / 9.81) = 2.9 deg) plus the magnitude's departure from g in radians
//    (| |f| - g | / g: a sample 1 m/s^2 off g adds ~6 deg), so a jolt is trusted little.
// The attitude is preferred when a frame has both: it is filtered, the accelerometer is not. The
// accelerometer is a source only when asked for (`from_accelerometer`): hand-held, its direction
// spreads 4-6 deg rms against the mocap on fr1_360_first60 and moved a fast turn more than it
// corrected it, and no rate of a few frames lets it average out before the map's direction is
// fixed; the flight controller's estimate has done that filtering already.
//
// The map's own gravity direction (`GravityReference`) is the weighted mean of the measured
// direction rotated into the world by the keyframes' poses, over the first `init_keyframes`
// keyframes; then it is held, so that later drift is measured against it instead of following it.
//
// Thread safety: GravityReference is owned by the tracking thread.
#pragma once

#include <Eigen/Geometry>
#include <optional>

#include "slam/core/types.hpp"

namespace rgbdquad::slam {

struct GravityOptions {
  /// On: a frame's gravity measurement constrains roll and pitch (pose fit, local BA, loop
  /// closing). Vision alone lets the first lap of a HIL flight tilt before the first loop
  /// correction; replayed without it, two flights' first laps drifted 1.4-1.7x as far
  /// (docs/slam.md). Frames without a measurement (no attitude, and the accelerometer not a
  /// source) are tracked as without it. Off: ablations.
  bool enabled = true;
  /// The Kinect's accelerometer as a source when a frame carries no attitude (see the header).
  bool from_accelerometer = false;
  double attitude_sigma_rad = 1.0 * M_PI / 180.0;
  double accel_base_sigma_rad = 3.0 * M_PI / 180.0;
  double standard_gravity_mps2 = 9.80665;
  /// Keyframes whose measurements define the map's gravity direction before it is held: ten
  /// keyframes span a few seconds of motion, over which a hand-held or hovering camera's
  /// accelerations average out.
  int init_keyframes = 10;
  bool is_valid(std::string* error) const;
};

/// The frame's gravity measurement (attitude first, then the accelerometer), or nullopt.
std::optional<GravityObservation> observe_gravity(const RgbdFrame& frame,
                                                  const GravityOptions& options);

/// The map's gravity direction in the world frame, from the first keyframes' measurements.
class GravityReference {
 public:
  explicit GravityReference(int init_keyframes = 10) : init_keyframes_(init_keyframes) {}
  /// Adds a keyframe's measurement (its camera-to-world rotation); ignored once held.
  void add(const Eigen::Matrix3d& R_world_cam, const GravityObservation& g);
  /// Unit vector, once at least one measurement was added.
  std::optional<Eigen::Vector3d> down_world() const;
  bool held() const { return added_ >= init_keyframes_; }

 private:
  int init_keyframes_;
  int added_ = 0;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
};

}  // namespace rgbdquad::slam
