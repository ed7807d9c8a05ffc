// Small planar geometry helpers of the control loop: angle wrapping and world->body rotation.
// Frames: the floor-aligned world frame has z up (height above the floor), x/y on the floor; yaw is
// measured counter-clockwise from world +x, seen from above, in degrees.
#pragma once

#include <cmath>

namespace rgbdquad::quadcontrol {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegPerRad = 180.0 / kPi;

/// Wraps an angle to [-180, 180) degrees.
inline double wrap_deg(double angle_deg) {
  double a = std::fmod(angle_deg + 180.0, 360.0);
  if (a < 0.0) a += 360.0;
  return a - 180.0;
}

/// Horizontal error expressed in the body frame of a craft with heading yaw_deg:
/// forward along the heading, left 90 degrees counter-clockwise from it.
struct BodyError {
  double forward_m = 0.0;
  double left_m = 0.0;
};

inline BodyError world_to_body(double error_x_m, double error_y_m, double yaw_deg) {
  const double c = std::cos(yaw_deg / kDegPerRad);
  const double s = std::sin(yaw_deg / kDegPerRad);
  return BodyError{c * error_x_m + s * error_y_m, -s * error_x_m + c * error_y_m};
}

/// Bearing (deg, counter-clockwise from +x) from (x0, y0) to (x1, y1).
inline double bearing_deg(double x0_m, double y0_m, double x1_m, double y1_m) {
  return std::atan2(y1_m - y0_m, x1_m - x0_m) * kDegPerRad;
}

}  // namespace rgbdquad::quadcontrol
