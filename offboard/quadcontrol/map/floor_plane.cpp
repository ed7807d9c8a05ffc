// RANSAC floor plane and floor-aligned frame: see floor_plane.hpp.
#include "map/floor_plane.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr double kMinPlaneArea = 1e-9;  // degenerate (collinear) sample triple
}  // namespace

bool FloorPlaneOptions::is_valid(std::string* error) const {
  if (iterations < 1) return reject(error, "floor.iterations must be >= 1");
  if (!(inlier_distance_m > 0.0)) return reject(error, "floor.inlier_distance_m must be > 0");
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 90.0))
    return reject(error, "floor.max_tilt_deg must be in (0, 90)");
  if (!(min_inlier_fraction > 0.0 && min_inlier_fraction <= 1.0))
    return reject(error, "floor.min_inlier_fraction must be in (0, 1]");
  return true;
}

Eigen::Matrix3d rotation_body_cam(double mount_pitch_down_deg) {
  // Level mount: camera z (forward) = body x, camera x (right) = body y, camera y (down) = body z;
  // then pitched down about body y, the forward axis tipping towards body +z.
  Eigen::Matrix3d level;
  level << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return Eigen::AngleAxisd(-mount_pitch_down_deg * kDegToRad, Eigen::Vector3d::UnitY())
             .toRotationMatrix() *
         level;
}

Eigen::Vector3d expected_up_in_camera(double mount_pitch_down_deg) {
  // Level camera: up = -y. Pitched down by a: up tilts backwards (-z): (0, -cos a, -sin a).
  return rotation_body_cam(mount_pitch_down_deg).transpose() * Eigen::Vector3d(0.0, 0.0, -1.0);
}

std::optional<FloorPlane> fit_floor_plane(const std::vector<Eigen::Vector3d>& points,
                                          const Eigen::Vector3d& expected_up_cam,
                                          const FloorPlaneOptions& options) {
  if (!options.is_valid(nullptr) || points.size() < 3) return std::nullopt;
  if (!expected_up_cam.allFinite() || expected_up_cam.norm() < 1e-9) return std::nullopt;
  const Eigen::Vector3d up = expected_up_cam.normalized();
  const double min_cos = std::cos(options.max_tilt_deg * kDegToRad);
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);

  std::optional<FloorPlane> best;
  for (int it = 0; it < options.iterations; ++it) {
    const Eigen::Vector3d& a = points[pick(rng)];
    const Eigen::Vector3d& b = points[pick(rng)];
    const Eigen::Vector3d& c = points[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < kMinPlaneArea) continue;
    n.normalize();
    if (n.dot(up) < 0.0) n = -n;
    if (n.dot(up) < min_cos) continue;
    double d = -n.dot(a);
    if (d <= 0.0) continue;  // camera must be above the plane
    std::size_t count = 0;
    for (const auto& p : points) {
      if (std::abs(n.dot(p) + d) <= options.inlier_distance_m) ++count;
    }
    // More support wins; within 20 % support the lower plane (larger d) wins: floor over table.
    const bool more_support = !best || static_cast<double>(count) > 1.2 * best->inliers;
    const bool similar_but_lower = best && static_cast<double>(count) * 1.2 >= best->inliers &&
                                   d > best->d_m + options.inlier_distance_m;
    const bool better = more_support || similar_but_lower;
    if (better) best = FloorPlane{n, d, count, 0.0};
  }
  if (!best) return std::nullopt;
  // Refine: least-squares plane through the inliers (SVD of the centred inliers).
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> inl;
  for (const auto& p : points) {
    if (std::abs(best->normal_cam.dot(p) + best->d_m) <= options.inlier_distance_m)
      inl.push_back(p);
  }
  for (const auto& p : inl) centroid += p;
  centroid /= static_cast<double>(inl.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : inl) cov += (p - centroid) * (p - centroid).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  Eigen::Vector3d n = solver.eigenvectors().col(0).normalized();
  if (n.dot(up) < 0.0) n = -n;
  FloorPlane plane{n, -n.dot(centroid), inl.size(),
                   static_cast<double>(inl.size()) / points.size()};
  if (plane.inlier_fraction < options.min_inlier_fraction || plane.d_m <= 0.0) return std::nullopt;
  return plane;
}

Eigen::Isometry3d floor_frame_from_plane(const FloorPlane& plane) {
  const Eigen::Vector3d z = plane.normal_cam.normalized();
  // x: optical axis projected on the floor (fallback: camera x when looking straight down).
  Eigen::Vector3d x = Eigen::Vector3d::UnitZ() - z * z.z();
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitX() - z * z.x();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R_floor_cam;
  R_floor_cam.row(0) = x.transpose();
  R_floor_cam.row(1) = y.transpose();
  R_floor_cam.row(2) = z.transpose();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R_floor_cam;
  // Camera centre (origin) maps to (0, 0, d): height above the floor.
  T.translation() = Eigen::Vector3d(0.0, 0.0, plane.d_m);
  return T;
}

}  // namespace rgbdquad::quadcontrol
