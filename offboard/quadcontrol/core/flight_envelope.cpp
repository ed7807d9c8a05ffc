// Flight envelope: see flight_envelope.hpp.
#include "core/flight_envelope.hpp"

#include <algorithm>
#include <cmath>

namespace rgbdquad::quadcontrol {

namespace {
bool finite(const SetpointPosition& p) {
  return std::isfinite(p.x_m) && std::isfinite(p.y_m) && std::isfinite(p.z_m);
}
}  // namespace

void FlightEnvelope::set_home(double x_m, double y_m) { home_ = SetpointPosition{x_m, y_m, 0.0}; }

std::optional<Contained> FlightEnvelope::contain(const SetpointPosition& wanted,
                                                 SetpointKind kind) const {
  if (!finite(wanted)) return std::nullopt;
  Contained out{wanted, false};
  if (home_ && kind != SetpointKind::kLanding) {
    const double dx = wanted.x_m - home_->x_m;
    const double dy = wanted.y_m - home_->y_m;
    if (!std::isfinite(dx) || !std::isfinite(dy)) return std::nullopt;
    if (std::hypot(dx, dy) > limits_.max_distance_from_home_m) {
      // Direction computed on the scaled-down offset: hypot of two values near DBL_MAX overflows.
      const double m = std::max(std::abs(dx), std::abs(dy));
      const double ux = dx / m;
      const double uy = dy / m;
      const double n = std::hypot(ux, uy);
      out.position.x_m = home_->x_m + limits_.max_distance_from_home_m * ux / n;
      out.position.y_m = home_->y_m + limits_.max_distance_from_home_m * uy / n;
      out.clamped = true;
    }
  }
  const double floor_m = kind == SetpointKind::kHold ? limits_.min_height_m : 0.0;
  const double z = std::clamp(wanted.z_m, floor_m, limits_.max_height_m);
  if (z != wanted.z_m) {
    out.position.z_m = z;
    out.clamped = true;
  }
  return out;
}

std::string FlightEnvelope::check_waypoint(double x_m, double y_m) const {
  if (!std::isfinite(x_m) || !std::isfinite(y_m)) return "waypoint: non-finite coordinates";
  if (!home_) return "waypoint: no home (take off first)";
  const double d = std::hypot(x_m - home_->x_m, y_m - home_->y_m);
  if (!std::isfinite(d) || d > limits_.max_distance_from_home_m) {
    return "waypoint: outside the flight envelope (further than max_distance_from_home_m from "
           "home)";
  }
  return {};
}

}  // namespace rgbdquad::quadcontrol
