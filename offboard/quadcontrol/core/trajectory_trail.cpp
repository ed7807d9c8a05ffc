// The dashboard's track: see trajectory_trail.hpp.
#include "core/trajectory_trail.hpp"

#include <algorithm>

namespace rgbdquad::quadcontrol {

void TrajectoryTrail::add(double x_m, double y_m) {
  if (points_.size() >= max_points_) points_.erase(points_.begin());
  points_.push_back({x_m, y_m});
}

std::vector<std::array<double, 2>> TrajectoryTrail::decimated() const {
  const std::size_t stride = std::max<std::size_t>(1, points_.size() / kShownPoints);
  std::vector<std::array<double, 2>> shown;
  shown.reserve(points_.size() / stride + 1);
  for (std::size_t i = 0; i < points_.size(); i += stride) shown.push_back(points_[i]);
  return shown;
}

}  // namespace rgbdquad::quadcontrol
