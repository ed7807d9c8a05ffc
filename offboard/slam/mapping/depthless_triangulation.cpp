// Triangulation of depthless keypoints; see depthless_triangulation.hpp.
#include "slam/mapping/depthless_triangulation.hpp"

#include <Eigen/SVD>
#include <cmath>
#include <limits>

#include "slam/tracking/projection_search.hpp"

namespace rgbdquad::slam {

namespace {

TriangulationKeyframe copy_keyframe(const MapKeyframe& kf) {
  TriangulationKeyframe out;
  out.id = kf.id;
  out.T_world_cam = kf.T_world_cam;
  out.depthless = kf.depthless;
  out.first_depthless = kf.features.size();
  out.free.resize(kf.depthless.size());
  for (std::size_t j = 0; j < kf.depthless.size(); ++j)
    out.free[j] = kf.point_ids[out.first_depthless + j] < 0;
  return out;
}

Eigen::Vector2d normalised(const CameraModel& cam, const Eigen::Vector2d& px) {
  return {(px.x() - cam.cx_px) / cam.fx_px, (px.y() - cam.cy_px) / cam.fy_px};
}

/// Squared whitened reprojection error of `p_world` at pixel `px` (sigma `sigma_px`) in camera
/// T_world_cam; infinity behind it.
double reprojection_chi2(const CameraModel& cam, const Eigen::Isometry3d& T_world_cam,
                         const Eigen::Vector3d& p_world, const Eigen::Vector2d& px,
                         double sigma_px) {
  const Eigen::Vector3d pc = T_world_cam.inverse() * p_world;
  if (pc.z() <= 0) return std::numeric_limits<double>::infinity();
  return ((cam.project(pc).head<2>() - px) / sigma_px).squaredNorm();
}

/// Matches of the keyframe's free depthless keypoints in one neighbour, then triangulated.
void triangulate_pair(const TriangulationKeyframe& a, const TriangulationKeyframe& b,
                      const CameraModel& cam, const TriangulationOptions& o,
                      std::vector<bool>* free_a, std::vector<bool>* free_b,
                      std::vector<TriangulatedPoint>* out) {
  const Eigen::Isometry3d T_b_a = b.T_world_cam.inverse() * a.T_world_cam;
  const Eigen::Vector3d t = T_b_a.translation();
  if (t.norm() < cam.bf_px_m / cam.fx_px) return;
  // Fundamental matrix from a's pixels to lines in b's: F = K^-T [t]x R K^-1.
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  Eigen::Matrix3d K;
  K << cam.fx_px, 0, cam.cx_px, 0, cam.fy_px, cam.cy_px, 0, 0, 1;
  const Eigen::Matrix3d Kinv = K.inverse();
  const Eigen::Matrix3d F = Kinv.transpose() * tx * T_b_a.linear() * Kinv;
  // a's centre in b: the epipole.
  const Eigen::Vector3d ca = T_b_a.translation();
  const bool epipole_ahead = ca.z() > 0;
  const Eigen::Vector2d epipole =
      epipole_ahead ? Eigen::Vector2d(cam.project(ca).head<2>()) : Eigen::Vector2d::Zero();
  const cv::Mat& da = a.depthless.features->descriptors;
  const cv::Mat& db = b.depthless.features->descriptors;
  for (std::size_t i = 0; i < a.depthless.size(); ++i) {
    if (!(*free_a)[i]) continue;
    const Eigen::Vector3d line = F * a.depthless.pixels[i].homogeneous();
    const double norm2 = line.head<2>().squaredNorm();
    if (!(norm2 > 0)) continue;
    double best = std::numeric_limits<double>::infinity(), second = best;
    int best_j = -1;
    const cv::Mat row_a = da.row(static_cast<int>(i));
    for (std::size_t j = 0; j < b.depthless.size(); ++j) {
      if (!(*free_b)[j]) continue;
      const Eigen::Vector2d& px = b.depthless.pixels[j];
      const double s2 = b.depthless.sigma_px[j] * b.depthless.sigma_px[j];
      const double dist = line.dot(px.homogeneous());
      if (dist * dist / norm2 >= o.epipolar_chi2 * s2) continue;
      if (epipole_ahead &&
          (px - epipole).norm() < o.min_epipole_distance_px * b.depthless.sigma_px[j])
        continue;
      const double d = descriptor_distance(row_a, db.row(static_cast<int>(j)));
      if (d < best) {
        second = best;
        best = d;
        best_j = static_cast<int>(j);
      } else if (d < second) {
        second = d;
      }
    }
    if (best_j < 0 || best > o.max_hamming) continue;
    if (second < std::numeric_limits<double>::infinity() && best > o.ratio * second) continue;
    const auto j = static_cast<std::size_t>(best_j);
    const Eigen::Vector2d xa = normalised(cam, a.depthless.pixels[i]);
    const Eigen::Vector2d xb = normalised(cam, b.depthless.pixels[j]);
    // Parallax of the two rays, in the world.
    const Eigen::Vector3d ray_a = a.T_world_cam.linear() * xa.homogeneous();
    const Eigen::Vector3d ray_b = b.T_world_cam.linear() * xb.homogeneous();
    const double cos_parallax = ray_a.dot(ray_b) / (ray_a.norm() * ray_b.norm());
    if (!(cos_parallax > 0 && cos_parallax < o.max_cos_parallax)) continue;
    const auto p = triangulate_linear(a.T_world_cam, xa, b.T_world_cam, xb);
    if (!p) continue;
    const double sa = a.depthless.sigma_px[i], sb = b.depthless.sigma_px[j];
    if (reprojection_chi2(cam, a.T_world_cam, *p, a.depthless.pixels[i], sa) > kChi2Mono95 ||
        reprojection_chi2(cam, b.T_world_cam, *p, b.depthless.pixels[j], sb) > kChi2Mono95)
      continue;
    const double dist_a = (*p - a.T_world_cam.translation()).norm();
    const double dist_b = (*p - b.T_world_cam.translation()).norm();
    if (!(dist_a > 0 && dist_b > 0)) continue;
    const double ratio_dist = dist_a / dist_b, ratio_scale = sa / sb;
    const double tolerance = 1.5 * o.scale_factor;
    if (ratio_dist * tolerance < ratio_scale || ratio_dist > ratio_scale * tolerance) continue;
    (*free_a)[i] = false;
    (*free_b)[j] = false;
    out->push_back(TriangulatedPoint{*p, a.id, b.id, static_cast<int>(a.first_depthless + i),
                                     static_cast<int>(b.first_depthless + j)});
  }
}

}  // namespace

std::optional<Eigen::Vector3d> triangulate_linear(const Eigen::Isometry3d& T_world_a,
                                                  const Eigen::Vector2d& x_a,
                                                  const Eigen::Isometry3d& T_world_b,
                                                  const Eigen::Vector2d& x_b) {
  const Eigen::Matrix<double, 3, 4> Pa = T_world_a.inverse().matrix().topRows<3>();
  const Eigen::Matrix<double, 3, 4> Pb = T_world_b.inverse().matrix().topRows<3>();
  Eigen::Matrix4d A;
  A.row(0) = x_a.x() * Pa.row(2) - Pa.row(0);
  A.row(1) = x_a.y() * Pa.row(2) - Pa.row(1);
  A.row(2) = x_b.x() * Pb.row(2) - Pb.row(0);
  A.row(3) = x_b.y() * Pb.row(2) - Pb.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  if (!(std::abs(h.w()) > 1e-12)) return std::nullopt;
  const Eigen::Vector3d p = h.head<3>() / h.w();
  if (!p.allFinite()) return std::nullopt;
  return p;
}

TriangulationView triangulation_view(const SlamMap& map, std::int64_t kf_id,
                                     const TriangulationOptions& options) {
  TriangulationView view;
  const MapKeyframe* kf = map.keyframe(kf_id);
  if (!kf || kf->depthless.size() == 0 || kf->depthless.features->descriptors.type() != CV_8U)
    return view;
  view.keyframe = copy_keyframe(*kf);
  for (const auto& [n, shared] : map.covisible(kf_id, 1)) {
    if (static_cast<int>(view.neighbours.size()) >= options.neighbours) break;
    const MapKeyframe* other = map.keyframe(n);
    if (other && other->depthless.size() > 0) view.neighbours.push_back(copy_keyframe(*other));
  }
  return view;
}

std::vector<TriangulatedPoint> triangulate_depthless(const TriangulationView& view,
                                                     const CameraModel& camera,
                                                     const TriangulationOptions& options) {
  std::vector<TriangulatedPoint> out;
  if (view.keyframe.id < 0) return out;
  std::vector<bool> free_a = view.keyframe.free;
  for (const TriangulationKeyframe& n : view.neighbours) {
    std::vector<bool> free_b = n.free;
    triangulate_pair(view.keyframe, n, camera, options, &free_a, &free_b, &out);
  }
  return out;
}

}  // namespace rgbdquad::slam
