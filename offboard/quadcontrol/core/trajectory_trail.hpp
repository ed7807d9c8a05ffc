// The craft's recent track on the floor for the dashboard: the newest `max_points` positions
// (x, y in the floor frame, metres), oldest dropped first, shown decimated to about 500 points so
// /api/state stays small however long the flight. Pure; not thread-safe (the owner guards it).
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace rgbdquad::quadcontrol {

class TrajectoryTrail {
 public:
  /// Points shown at most about this many: every n-th point, n = size / 500.
  static constexpr std::size_t kShownPoints = 500;

  explicit TrajectoryTrail(std::size_t max_points) : max_points_(max_points) {}

  /// Appends a position; the oldest is dropped once `max_points` are held.
  void add(double x_m, double y_m);
  std::size_t size() const { return points_.size(); }
  /// Every n-th point from the oldest, n = max(1, size / kShownPoints).
  std::vector<std::array<double, 2>> decimated() const;

 private:
  std::size_t max_points_;
  std::vector<std::array<double, 2>> points_;
};

}  // namespace rgbdquad::quadcontrol
