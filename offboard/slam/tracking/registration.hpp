// Registering a frame's features against map points, shared by tracking (recovery and
// relocalisation) and loop closing (geometric verification):
//  - `register_to_keyframe`: descriptor matches between the frame and one keyframe's map points,
//    then 3D-3D RANSAC (RGB-D: a rigid SE(3) motion, no scale) -> a pose guess;
//  - `fit_by_projection`: two-pass projection matching against a set of map points from a pose
//    guess with motion-only optimisation in between (ORB-SLAM2's TrackLocalMap shape).
//
// Pure functions; callers copy what they need out of the map under its lock first.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "slam/map/map.hpp"
#include "slam/matching/matching.hpp"
#include "slam/motion/motion.hpp"
#include "slam/tracking/pose_optimizer.hpp"
#include "slam/tracking/projection_search.hpp"

namespace rgbdquad::slam {

/// A keyframe's map points as the registration needs them (world positions, point ids, and the
/// descriptors of the keypoints that see them).
struct KeyframePoints {
  std::int64_t keyframe = -1;
  std::vector<Eigen::Vector3d> p_world_m;
  std::vector<std::int64_t> point_ids;
  cv::Mat descriptors;
};
/// Copies keyframe `kf_id`'s points (call with the map locked). Empty if the keyframe is gone.
KeyframePoints keyframe_points(const SlamMap& map, std::int64_t kf_id);

struct Registration {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  std::size_t matches = 0, inliers = 0;
};
/// Pose of the frame from descriptor matches to `kp` and 3D-3D RANSAC; nullopt below
/// `min_inliers` RANSAC inliers (or too few pairs for RANSAC).
std::optional<Registration> register_to_keyframe(const FrameFeatures& frame,
                                                 const KeyframePoints& kp,
                                                 const MatchOptions& matching,
                                                 const RansacOptions& ransac, std::uint64_t seed,
                                                 int min_inliers);

struct ProjectionFitOptions {
  ProjectionSearchOptions search;  ///< first pass (its radius is the caller's first radius)
  double refine_radius_px = 3.0;   ///< second pass around the refined pose
  double wide_radius_factor =
      3.0;  ///< first pass repeated this much wider when it finds too little
  int min_matches_first_pass = 20;
  PoseOptimizerOptions pose;
};
struct ProjectionFit {
  bool ok = false;
  Eigen::Isometry3d T_cam_world = Eigen::Isometry3d::Identity();
  std::vector<int> point_of_keypoint;  ///< inlier matches only (index into the point list)
  std::size_t matches = 0, inliers = 0;
  /// Matches of the frame's keypoints without depth (FrameFeatures::depthless), inliers only,
  /// observed as (u, v) in the fit. Not counted in `matches` / `inliers`: the bars on those
  /// (tracking, relocalisation, keyframes) were set for RGB-D matches and stay so.
  std::vector<int> point_of_depthless;
  std::size_t depthless_inliers = 0;
};
/// Two-pass projection matching and pose optimisation of `frame` against `points` from a guess.
/// With `depthless` (the same frame's keypoints without depth), points not matched to a keypoint
/// with depth are matched to those too and enter the fit as monocular observations.
ProjectionFit fit_by_projection(const std::vector<LocalPoint>& points, const TrackedFeatures& frame,
                                const CameraModel& camera,
                                const Eigen::Isometry3d& T_cam_world_guess, double first_radius_px,
                                const ProjectionFitOptions& options,
                                const TrackedFeatures* depthless = nullptr);

/// The observation of map point `p_world_m` by keypoint `k` of `frame` for the pose fit; for a
/// depthless keypoint (`monocular`) its pixel only.
PoseObservation pose_observation(const Eigen::Vector3d& p_world_m, const TrackedFeatures& frame,
                                 std::size_t k, const CameraModel& camera, bool monocular);

}  // namespace rgbdquad::slam
