// Loop-closure decisions as pure functions (thesis Sec. 3.4):
//  - Local loop closure (LLC): a non-keyframe's pose is pulled towards the pose measured against
//  its
//    best recent keyframe, but the correction is limited to `llc_max_fraction` (25 %) of the
//    frame's own edge (its frame-to-frame motion), in translation and in rotation angle.
//  - Global loop closure (GLC) candidates: the older keyframes (the latest 3 excluded) are split
//    into 7 blocks spread evenly in time; each back-end iteration tests one keyframe per block,
//    rotating through each block from one iteration to the next.
// Thread-safe (stateless).
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rgbdquad::slam {

struct LoopOptions {
  double llc_max_fraction = 0.25;         ///< thesis: correction <= 25 % of the frame's edge
  int glc_blocks = 7;                     ///< thesis: 7 keyframes spread over the older sequence
  int glc_exclude_latest = 3;             ///< thesis: the latest 3 keyframes are excluded
  double glc_min_match_fraction = 0.20;   ///< thesis: candidate when >= 20 % of features match
  double glc_min_inlier_fraction = 0.60;  ///< thesis: accepted when RANSAC inliers >= 60 %
  bool glc_test_neighbours = true;        ///< thesis: also test the two neighbouring keyframes
  bool is_valid(std::string* error) const;
};

/// LLC: returns the pose between `T_world_cam_predicted` and `T_world_cam_measured`, moved from the
/// prediction towards the measurement by at most `max_fraction` of the edge's translation length
/// and rotation angle (`T_prev_cur_edge`, the frame's own motion). Non-finite input returns the
/// prediction unchanged.
Eigen::Isometry3d clamp_llc_correction(const Eigen::Isometry3d& T_world_cam_predicted,
                                       const Eigen::Isometry3d& T_world_cam_measured,
                                       const Eigen::Isometry3d& T_prev_cur_edge,
                                       double max_fraction);

/// GLC: indices (0-based, into the `older_count` older keyframes ordered by recency position) to
/// test at back-end iteration `iteration`. With fewer older keyframes than blocks, every one is
/// tested. Block b covers [b*n/B, (b+1)*n/B); its member (iteration mod block size) is chosen.
std::vector<std::size_t> select_glc_candidates(std::size_t older_count, std::size_t iteration,
                                               int blocks);

/// GLC: the keyframe ids to test at back-end iteration `iteration`. `recency` holds the keyframe
/// ids least recently used first; `self_id` (the frame, if it just became a keyframe) and the
/// latest `glc_exclude_latest` are left out, the rest thinned by select_glc_candidates.
std::vector<std::int64_t> glc_keyframes_to_test(const std::vector<std::int64_t>& recency,
                                                std::int64_t self_id, std::size_t iteration,
                                                const LoopOptions& options);

/// GLC acceptance of one tested keyframe: at least `glc_min_match_fraction` of the frame's
/// `n_features` matched, RANSAC kept at least `glc_min_inlier_fraction` of the matches and at
/// least `min_inliers` (the back-end's own bar for any usable estimate).
bool accept_glc_match(const LoopOptions& options, std::size_t n_features, std::size_t matches,
                      double inlier_ratio, std::size_t inliers, std::size_t min_inliers);

}  // namespace rgbdquad::slam
