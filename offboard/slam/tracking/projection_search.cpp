// Matching by projection; see projection_search.hpp.
#include "slam/tracking/projection_search.hpp"

#include <cmath>
#include <limits>
#include <opencv2/core/hal/hal.hpp>

#include "slam/matching/matching.hpp"

namespace rgbdquad::slam {

double descriptor_distance(const cv::Mat& a, const cv::Mat& b) {
  // Raw-pointer kernels: this runs tens of thousands of times per frame.
  if (a.type() == CV_8U)
    return cv::hal::normHamming(a.ptr<std::uint8_t>(), b.ptr<std::uint8_t>(), a.cols);
  return std::sqrt(
      static_cast<double>(cv::hal::normL2Sqr_(a.ptr<float>(), b.ptr<float>(), a.cols)));
}

ProjectionMatches search_by_projection(const std::vector<LocalPoint>& points,
                                       const Eigen::Isometry3d& T_cam_world,
                                       const TrackedFeatures& frame, const CameraModel& cam,
                                       const ProjectionSearchOptions& o,
                                       const std::vector<int>* preset,
                                       const std::vector<bool>* skip_points) {
  ProjectionMatches out;
  const std::size_t nk = frame.size();
  out.point_of_keypoint = preset ? *preset : std::vector<int>(nk, -1);
  out.visible.assign(points.size(), false);
  std::vector<double> best_dist(nk, std::numeric_limits<double>::infinity());
  std::vector<bool> locked(nk, false);
  if (preset)
    for (std::size_t k = 0; k < nk; ++k) locked[k] = (*preset)[k] >= 0;
  std::vector<bool> already = skip_points && skip_points->size() == points.size()
                                  ? *skip_points
                                  : std::vector<bool>(points.size(), false);
  if (preset)
    for (std::size_t k = 0; k < nk; ++k)
      if ((*preset)[k] >= 0) already[static_cast<std::size_t>((*preset)[k])] = true;
  const cv::Mat& desc = frame.features->descriptors;
  const bool binary = desc.type() == CV_8U;
  std::vector<cv::Mat> rows(nk);  // row headers made once per frame, not once per candidate
  for (std::size_t k = 0; k < nk; ++k) rows[k] = desc.row(static_cast<int>(k));
  // Grid query radius: the search radius of the coarsest keypoint in this frame.
  double max_sigma = 1.0;
  for (double sg : frame.sigma_px) max_sigma = std::max(max_sigma, sg);
  const double query_radius_px = o.radius_px * std::min(max_sigma, 4.0);
  std::vector<int> cand;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d pc = T_cam_world * points[i].p_world_m;
    if (pc.z() < o.min_depth_m) continue;
    const Eigen::Vector3d uvd = cam.project(pc);
    if (!cam.in_image(uvd.x(), uvd.y())) continue;
    out.visible[i] = true;
    if (already[i]) continue;
    // The search radius grows with the coarsest level a match may come from; candidates are
    // checked against their own sigma below.
    frame.grid.query(uvd.x(), uvd.y(), query_radius_px, &cand);
    double best = std::numeric_limits<double>::infinity(), second = best;
    int best_k = -1;
    for (int k : cand) {
      const auto ks = static_cast<std::size_t>(k);
      if (locked[ks]) continue;
      const double r = o.radius_px * frame.sigma_px[ks];
      if ((frame.pixels[ks] - uvd.head<2>()).squaredNorm() > r * r) continue;
      const double d = descriptor_distance(points[i].descriptor, rows[ks]);
      if (d < best) {
        second = best;
        best = d;
        best_k = k;
      } else if (d < second) {
        second = d;
      }
    }
    if (best_k < 0) continue;
    const double gate =
        binary ? o.max_hamming
               : o.nnmmt_fraction * distance_to_origin(rows[static_cast<std::size_t>(best_k)]);
    if (best > gate) continue;
    if (second < std::numeric_limits<double>::infinity() && best > o.ratio * second) continue;
    const auto bk = static_cast<std::size_t>(best_k);
    if (best < best_dist[bk]) {
      best_dist[bk] = best;
      out.point_of_keypoint[bk] = static_cast<int>(i);
    }
  }
  out.matches = 0;
  for (int p : out.point_of_keypoint) out.matches += p >= 0 ? 1 : 0;
  return out;
}

std::vector<bool> matched_points(const std::vector<int>& point_of_keypoint, std::size_t n_points) {
  std::vector<bool> out(n_points, false);
  for (int p : point_of_keypoint)
    if (p >= 0 && static_cast<std::size_t>(p) < n_points) out[static_cast<std::size_t>(p)] = true;
  return out;
}

}  // namespace rgbdquad::slam
