// Frame-to-map registration; see registration.hpp.
#include "slam/tracking/registration.hpp"

#include <algorithm>
#include <numeric>

namespace rgbdquad::slam {

KeyframePoints keyframe_points(const SlamMap& map, std::int64_t kf_id) {
  KeyframePoints out;
  const MapKeyframe* kf = map.keyframe(kf_id);
  if (!kf) return out;
  out.keyframe = kf_id;
  std::vector<int> rows;
  for (std::size_t k = 0; k < kf->features.size(); ++k) {  // keypoints with depth: RANSAC's pairs
    const MapPoint* p = kf->point_ids[k] >= 0 ? map.point(kf->point_ids[k]) : nullptr;
    if (!p) continue;
    out.p_world_m.push_back(p->p_world_m);
    out.point_ids.push_back(p->id);
    rows.push_back(static_cast<int>(k));
  }
  const cv::Mat& all = kf->features.features->descriptors;
  out.descriptors.create(static_cast<int>(rows.size()), all.cols, all.type());
  for (std::size_t r = 0; r < rows.size(); ++r)
    all.row(rows[r]).copyTo(out.descriptors.row(static_cast<int>(r)));
  return out;
}

std::optional<Registration> register_to_keyframe(const FrameFeatures& frame,
                                                 const KeyframePoints& kp,
                                                 const MatchOptions& matching,
                                                 const RansacOptions& ransac, std::uint64_t seed,
                                                 int min_inliers) {
  if (kp.p_world_m.size() < ransac.min_pairs) return std::nullopt;
  const std::vector<Match> m = match_descriptors(frame.descriptors, kp.descriptors, matching);
  if (m.size() < ransac.min_pairs) return std::nullopt;
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<int> order(m.size());
  for (const Match& x : m) {
    src.push_back(frame.points_cam_m[static_cast<std::size_t>(x.query)]);
    dst.push_back(kp.p_world_m[static_cast<std::size_t>(x.train)]);
  }
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return m[static_cast<std::size_t>(a)].distance < m[static_cast<std::size_t>(b)].distance;
  });
  auto est = estimate_motion_ransac(src, dst, order, ransac, seed, nullptr);
  if (!est || est->inliers.size() < static_cast<std::size_t>(min_inliers)) return std::nullopt;
  return Registration{est->T_dst_src, m.size(), est->inliers.size()};
}

PoseObservation pose_observation(const Eigen::Vector3d& p_world_m, const TrackedFeatures& frame,
                                 std::size_t k, const CameraModel& camera, bool monocular) {
  if (!monocular) return PoseObservation{p_world_m, frame.measurement(k, camera), frame.sigma(k)};
  const double s = frame.sigma_px[k];
  return PoseObservation{p_world_m, Eigen::Vector3d(frame.pixels[k].x(), frame.pixels[k].y(), 0),
                         Eigen::Vector3d(s, s, 1), true};
}

ProjectionFit fit_by_projection(const std::vector<LocalPoint>& points, const TrackedFeatures& frame,
                                const CameraModel& camera, const Eigen::Isometry3d& T_guess,
                                double first_radius_px, const ProjectionFitOptions& options,
                                const TrackedFeatures* depthless) {
  ProjectionFit fit;
  ProjectionSearchOptions so = options.search;
  so.radius_px = first_radius_px;
  ProjectionMatches m = search_by_projection(points, T_guess, frame, camera, so);
  if (m.matches < options.min_matches_first_pass) {
    so.radius_px = first_radius_px * options.wide_radius_factor;
    m = search_by_projection(points, T_guess, frame, camera, so);
  }
  if (m.matches < 6) return fit;
  // The depthless keypoints' matches, to points no keypoint with depth took.
  auto search_depthless = [&](const Eigen::Isometry3d& T, const std::vector<int>& taken,
                              const std::vector<int>* preset) {
    if (!depthless || depthless->size() == 0) return std::vector<int>{};
    const std::vector<bool> skip = matched_points(taken, points.size());
    return search_by_projection(points, T, *depthless, camera, so, preset, &skip).point_of_keypoint;
  };
  // Optimises from `T_start` on the matches `pok` (keypoints with depth) and `pod` (without);
  // `kept` / `kept_depthless` receive the inlier matches only.
  auto optimise = [&](const std::vector<int>& pok, const std::vector<int>& pod,
                      const Eigen::Isometry3d& T_start, std::vector<int>* kept,
                      std::vector<int>* kept_depthless) {
    std::vector<PoseObservation> obs;
    std::vector<int> kp_of_obs;
    auto add = [&](const std::vector<int>& matches, const TrackedFeatures& f, bool monocular) {
      for (std::size_t k = 0; k < matches.size(); ++k) {
        if (matches[k] < 0) continue;
        obs.push_back(pose_observation(points[static_cast<std::size_t>(matches[k])].p_world_m, f, k,
                                       camera, monocular));
        kp_of_obs.push_back(static_cast<int>(k));
      }
    };
    add(pok, frame, false);
    const std::size_t n_rgbd = obs.size();
    if (depthless) add(pod, *depthless, true);
    const PoseOptimizerResult r = optimize_pose(T_start, obs, camera, options.pose);
    kept->assign(pok.size(), -1);
    kept_depthless->assign(pod.size(), -1);
    if (!r.ok) return std::make_pair(r, 0);
    int rgbd_inliers = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      if (!r.inlier[i]) continue;
      const auto k = static_cast<std::size_t>(kp_of_obs[i]);
      if (i < n_rgbd) {
        (*kept)[k] = pok[k];
        ++rgbd_inliers;
      } else {
        (*kept_depthless)[k] = pod[k];
      }
    }
    return std::make_pair(r, rgbd_inliers);
  };
  std::vector<int> kept, kept_depthless;
  const auto [first, first_inliers] =
      optimise(m.point_of_keypoint, search_depthless(T_guess, m.point_of_keypoint, nullptr),
               T_guess, &kept, &kept_depthless);
  if (!first.ok || first_inliers < 6) return fit;
  // Second pass: keep the inliers, look for more points around the refined projections.
  so.radius_px = options.refine_radius_px;
  // Points the depthless keypoints hold stay theirs; without them (the default) nothing to skip.
  const std::vector<bool> taken_depthless =
      depthless ? matched_points(kept_depthless, points.size()) : std::vector<bool>{};
  const ProjectionMatches m2 = search_by_projection(points, first.T_cam_world, frame, camera, so,
                                                    &kept, depthless ? &taken_depthless : nullptr);
  std::vector<int> kept2, kept2_depthless;
  const auto [second, second_inliers] =
      optimise(m2.point_of_keypoint,
               search_depthless(first.T_cam_world, m2.point_of_keypoint, &kept_depthless),
               first.T_cam_world, &kept2, &kept2_depthless);
  if (!second.ok) return fit;
  fit.ok = true;
  fit.T_cam_world = second.T_cam_world;
  fit.point_of_keypoint = std::move(kept2);
  fit.matches = static_cast<std::size_t>(m2.matches);
  fit.inliers = static_cast<std::size_t>(second_inliers);
  for (int p : kept2_depthless) fit.depthless_inliers += p >= 0 ? 1 : 0;
  fit.point_of_depthless = std::move(kept2_depthless);
  return fit;
}

}  // namespace rgbdquad::slam
