// Gravity consistency: mean direction, angles to it, and the axis-aligned candidate rotations.
#include "slam/motion/gravity_consistency.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace rgbdquad::slam {

std::optional<GravitySpread> gravity_direction_spread(
    const std::vector<Eigen::Matrix3d>& R_world_cam, const std::vector<Eigen::Vector3d>& f_cam) {
  if (R_world_cam.size() != f_cam.size() || f_cam.size() < 2) return std::nullopt;
  std::vector<Eigen::Vector3d> dirs;
  dirs.reserve(f_cam.size());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < f_cam.size(); ++i) {
    const Eigen::Vector3d u = R_world_cam[i] * f_cam[i];
    const double n = u.norm();
    if (!u.allFinite() || !(n > 0)) return std::nullopt;
    dirs.push_back(u / n);
    sum += dirs.back();
  }
  if (!(sum.norm() > 0)) return std::nullopt;
  GravitySpread s;
  s.samples = dirs.size();
  s.mean_direction_world = sum.normalized();
  std::vector<double> angles_deg;
  angles_deg.reserve(dirs.size());
  double sq = 0;
  for (const Eigen::Vector3d& d : dirs) {
    // atan2 of |cross| and dot: accurate at small angles, where acos of a dot near 1 is not.
    const double a =
        std::atan2(d.cross(s.mean_direction_world).norm(), d.dot(s.mean_direction_world)) * 180.0 /
        M_PI;
    angles_deg.push_back(a);
    sq += a * a;
  }
  s.rms_deg = std::sqrt(sq / static_cast<double>(angles_deg.size()));
  std::sort(angles_deg.begin(), angles_deg.end());
  s.max_deg = angles_deg.back();
  // Nearest-rank percentile: the smallest angle with at least 95 % of the samples at or below it.
  const auto rank =
      static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(angles_deg.size())));
  s.p95_deg = angles_deg[std::max<std::size_t>(rank, 1) - 1];
  return s;
}

std::vector<std::array<double, 9>> axis_aligned_rotations() {
  std::vector<std::array<double, 9>> out;
  std::array<int, 3> perm{0, 1, 2};
  do {
    for (int signs = 0; signs < 8; ++signs) {
      Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
      for (int row = 0; row < 3; ++row) R(row, perm[row]) = (signs >> row) & 1 ? -1.0 : 1.0;
      if (R.determinant() < 0) continue;  // a reflection: no mounting produces it
      out.push_back(
          {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)});
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  return out;
}

}  // namespace rgbdquad::slam
