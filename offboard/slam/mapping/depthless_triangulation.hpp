// Map points from keypoints without depth (ORB-SLAM2's CreateNewMapPoints, for the keypoints an
// RGB-D camera leaves without a reading): a new keyframe's free depthless keypoints are matched to
// its covisible keyframes' free depthless keypoints along the epipolar line and triangulated.
// Where the view's far half lies beyond the depth range (a far wall, the far side of a room) the
// map otherwise has no points there at all, and the rotation about a horizontal axis rests on the
// near floor alone; these points give tracking's monocular observations something to match.
//
// Pure: reads a snapshot (TriangulationView), returns candidate points; the mapper adds them.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "slam/map/map.hpp"

namespace rgbdquad::slam {

struct TriangulationOptions {
  int neighbours = 10;  ///< ORB-SLAM2 CreateNewMapPoints: 10 covisible keyframes (RGB-D/stereo)
  /// ORB-SLAM2's TH_LOW: the descriptor distance a triangulation match may have (ORB, bits). Float
  /// descriptors (SIFT/SURF) are not triangulated.
  double max_hamming = 50;
  /// Best over second-best descriptor distance among the candidates on the epipolar line: the
  /// nearest-neighbour ratio ORB-SLAM2's local mapper builds its matcher with (0.6). Brute force
  /// along the line sees more candidates than ORB-SLAM2's vocabulary-node search, so the ratio is
  /// applied where ORB-SLAM2 applies none.
  double ratio = 0.6;
  /// ORB-SLAM2 CheckDistEpipolarLine: squared distance to the epipolar line below 3.84 sigma^2
  /// (the 95 % chi-square bound for one degree of freedom).
  double epipolar_chi2 = 3.84;
  /// ORB-SLAM2: a keypoint nearer the epipole than 100 px x its level scale is skipped (its ray
  /// is nearly the baseline; depth there is unobservable).
  double min_epipole_distance_px = 100;
  /// ORB-SLAM2: rays must diverge by cos < 0.9998 (1.15 deg) for a depth worth keeping.
  double max_cos_parallax = 0.9998;
  /// ORB-SLAM2 scale consistency: the ratio of the point's distances from the two cameras must
  /// agree with the ratio of the keypoints' level scales within 1.5 x the pyramid's scale factor.
  double scale_factor = 2.0;  ///< the pyramid's scale factor (FeatureOptions::orb_scale_factor)
};

/// One keyframe's share of a triangulation: pose and its free depthless keypoints.
struct TriangulationKeyframe {
  std::int64_t id = -1;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  TrackedFeatures depthless;
  std::size_t first_depthless = 0;  ///< keypoint index of depthless keypoint 0 (features.size())
  std::vector<bool> free;           ///< per depthless keypoint: sees no point yet
};

/// A new keyframe and its covisible neighbours, copied under the map lock.
struct TriangulationView {
  TriangulationKeyframe keyframe;
  std::vector<TriangulationKeyframe> neighbours;
};

struct TriangulatedPoint {
  Eigen::Vector3d p_world_m = Eigen::Vector3d::Zero();
  std::int64_t kf_a = -1, kf_b = -1;  ///< the new keyframe and the neighbour
  int kp_a = -1, kp_b = -1;           ///< keypoint indices in each (depthless range)
};

/// Copies keyframe `kf_id` and its best covisible neighbours that hold depthless keypoints. Call
/// with the map locked. Empty `keyframe.id` (-1) when the keyframe has none.
TriangulationView triangulation_view(const SlamMap& map, std::int64_t kf_id,
                                     const TriangulationOptions& options);

/// Matches and triangulates; each keypoint is used at most once. Neighbours nearer the keyframe
/// than the camera's stereo baseline (bf / fx, ORB-SLAM2's bound for RGB-D) are skipped.
std::vector<TriangulatedPoint> triangulate_depthless(const TriangulationView& view,
                                                     const CameraModel& camera,
                                                     const TriangulationOptions& options);

/// Linear (DLT) triangulation of a point seen at normalised image coordinates `x_a` and `x_b`
/// (z = 1 bearings) by cameras T_world_a and T_world_b. nullopt when degenerate.
std::optional<Eigen::Vector3d> triangulate_linear(const Eigen::Isometry3d& T_world_a,
                                                  const Eigen::Vector2d& x_a,
                                                  const Eigen::Isometry3d& T_world_b,
                                                  const Eigen::Vector2d& x_b);

}  // namespace rgbdquad::slam
