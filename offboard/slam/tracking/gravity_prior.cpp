// Gravity as a roll/pitch prior; see gravity_prior.hpp.
#include "slam/tracking/gravity_prior.hpp"

#include <cmath>
#include <string>

namespace rgbdquad::slam {

bool GravityOptions::is_valid(std::string* error) const {
  if (!(attitude_sigma_rad > 0) || !(accel_base_sigma_rad > 0) || !(standard_gravity_mps2 > 0) ||
      init_keyframes < 1) {
    if (error) *error = "gravity: sigmas and g must be positive, init_keyframes >= 1";
    return false;
  }
  return true;
}

std::optional<GravityObservation> observe_gravity(const RgbdFrame& frame, const GravityOptions& o) {
  if (frame.q_nav_cam && frame.q_nav_cam->coeffs().allFinite() && frame.q_nav_cam->norm() > 0.5) {
    // NED: gravity is +z of the navigation frame; in the camera frame R_cam_nav * z.
    const Eigen::Matrix3d R_nav_cam = frame.q_nav_cam->normalized().toRotationMatrix();
    return GravityObservation{R_nav_cam.transpose() * Eigen::Vector3d::UnitZ(),
                              o.attitude_sigma_rad};
  }
  if (o.from_accelerometer && frame.accel_cam_mps2 && frame.accel_cam_mps2->allFinite()) {
    const double magnitude = frame.accel_cam_mps2->norm();
    if (!(magnitude > 0)) return std::nullopt;
    const double departure_rad =
        std::abs(magnitude - o.standard_gravity_mps2) / o.standard_gravity_mps2;
    return GravityObservation{-*frame.accel_cam_mps2 / magnitude,
                              o.accel_base_sigma_rad + departure_rad};
  }
  return std::nullopt;
}

void GravityReference::add(const Eigen::Matrix3d& R_world_cam, const GravityObservation& g) {
  if (held() || !(g.sigma_rad > 0)) return;
  sum_ += (R_world_cam * g.down_cam) / (g.sigma_rad * g.sigma_rad);
  ++added_;
}

std::optional<Eigen::Vector3d> GravityReference::down_world() const {
  if (added_ == 0 || !(sum_.norm() > 0)) return std::nullopt;
  return sum_.normalized();
}

}  // namespace rgbdquad::slam
