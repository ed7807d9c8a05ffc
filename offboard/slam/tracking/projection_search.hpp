// Matching by projection: map points are projected with a predicted camera pose and each is
// matched to the most similar keypoint within a radius of its projection (grid lookup, no brute
// force over the frame). A keypoint keeps only its best point. Descriptor gates:
//  - binary (ORB): Hamming distance <= 100 of 256 bits (ORB-SLAM2's TH_HIGH for projection search);
//  - float (SIFT/SURF): L2 distance <= half the descriptor's norm (the thesis' NNMMT rule);
//  - both: best < 0.8 x second best among the candidates (ORB-SLAM2's ratio for local-map search;
//    looser than the thesis' 0.6 because the projection already rejects most wrong candidates).
//
// Stateless and thread-safe.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "slam/map/map.hpp"

namespace rgbdquad::slam {

/// A map point as tracking sees it (a snapshot: position and descriptor at the time of the copy).
struct LocalPoint {
  std::int64_t id = -1;
  Eigen::Vector3d p_world_m = Eigen::Vector3d::Zero();
  cv::Mat descriptor;
};

struct ProjectionSearchOptions {
  double radius_px = 15.0;      ///< search radius at the finest level; scaled by keypoint sigma
  int max_hamming = 100;        ///< ORB-SLAM2 TH_HIGH
  double nnmmt_fraction = 0.5;  ///< thesis Sec. 3.4
  double ratio = 0.8;           ///< ORB-SLAM2 SearchByProjection(local map) nnratio
  double min_depth_m = 0.1;     ///< points behind or too near the camera are not projected
};

/// Descriptor distance: Hamming for CV_8U rows, L2 for CV_32F rows.
double descriptor_distance(const cv::Mat& a, const cv::Mat& b);

struct ProjectionMatches {
  std::vector<int> point_of_keypoint;  ///< per keypoint: index into the LocalPoint list, or -1
  std::vector<bool> visible;           ///< per LocalPoint: projected inside the image
  int matches = 0;
};

/// `preset` (optional, per keypoint): keypoints already matched are left as they are, and their
/// points are not matched again. `skip_points` (optional, per LocalPoint): points matched
/// elsewhere (to another keypoint set of the same frame) are not matched either.
ProjectionMatches search_by_projection(const std::vector<LocalPoint>& points,
                                       const Eigen::Isometry3d& T_cam_world,
                                       const TrackedFeatures& frame, const CameraModel& camera,
                                       const ProjectionSearchOptions& options,
                                       const std::vector<int>* preset = nullptr,
                                       const std::vector<bool>* skip_points = nullptr);

/// Per LocalPoint of `n_points`: whether a keypoint of `point_of_keypoint` is matched to it.
std::vector<bool> matched_points(const std::vector<int>& point_of_keypoint, std::size_t n_points);

}  // namespace rgbdquad::slam
