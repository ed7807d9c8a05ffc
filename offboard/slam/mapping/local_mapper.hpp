// Local mapping: runs once per new keyframe, off the camera-to-command path. Steps (ORB-SLAM2's
// LocalMapping order, adapted to RGB-D where every keyframe brings its own depth):
//  1. cull recently created points that tracking rarely finds (found/visible < 25 %) or that no
//     second keyframe has observed two keyframes after their creation (an observation without
//     depth counts half, as ORB-SLAM2 counts a stereo observation twice: a triangulated point
//     needs a third keyframe); with `triangulate_depthless`, then triangulate new points from
//     the keyframe's depthless keypoints and its neighbours' (depthless_triangulation.hpp);
//  2. fuse: project the new keyframe's points into its covisible keyframes and theirs into it; a
//     keypoint that already sees another point merges the two, otherwise it gains an observation
//     (this is what links revisited places and keeps duplicates out);
//  3. local bundle adjustment with Ceres over a bounded window (the new keyframe and its most
//     covisible neighbours; keyframes outside the window that see the same points are held fixed):
//     keyframe poses and points, RGB-D reprojection residual, Huber kernel, then outlier
//     observations removed by the chi-square test; with gravity measured (TrackerOptions::gravity)
//     each window keyframe also gets a roll/pitch factor (slam/core/types.hpp gravity_residual);
//  4. cull redundant keyframes: one whose points are 90 % seen by at least 3 other keyframes.
// Cost per keyframe is bounded by the window sizes, not by the length of the flight.
// Catching up (ORB-SLAM2's CheckNewKeyFrames / abort flag): when the caller says more keyframes
// wait, steps 2-4 are left to the newest keyframe, and a bundle adjustment under way stops at the
// end of its current iteration, keeping what it has reached. A mapper that falls behind (a loaded
// CPU) thus spends its time on the keyframe tracking is about to use, not on a backlog.
//
// Thread safety: one LocalMapper; it locks the shared map for copies and write-backs and solves
// the bundle adjustment on a copy, so tracking never waits for the solver.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam/mapping/depthless_triangulation.hpp"
#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

struct LocalMapperOptions {
  double min_found_ratio = 0.25;  ///< ORB-SLAM2 MapPointCulling
  int cull_after_keyframes = 2;   ///< ORB-SLAM2: judged 2 keyframes after creation...
  int min_observing_keyframes =
      2;                     ///< ...must be seen by 2 keyframes (3 "observations", stereo counts 2)
  int fuse_neighbours = 10;  ///< ORB-SLAM2 SearchInNeighbors (monocular 20 -> we keep it bounded)
  double fuse_radius_px = 3.0;       ///< ORB-SLAM2 Fuse th = 3 (times the keypoint sigma)
  int ba_window = 10;                ///< keyframes optimised per run
  int ba_max_fixed = 20;             ///< fixed keyframes that anchor the window
  int ba_iterations = 10;            ///< ORB-SLAM2: 5 robust + 10 refinement; we do one robust pass
  int covisibility_min_shared = 15;  ///< ORB-SLAM2's threshold for a covisibility edge
  double redundant_fraction = 0.9;   ///< ORB-SLAM2 KeyFrameCulling
  int redundant_observers = 3;
  double near_depth_m = 3.1;  ///< as TrackerOptions::near_depth_m
  bool bundle_adjustment = true;
  /// Triangulate map points from the keyframes' depthless keypoints (TrackerOptions::
  /// depthless_map_points keeps them in keyframes); their observations enter local BA in (u, v).
  bool triangulate_depthless = true;
  TriangulationOptions triangulation;
  bool is_valid(std::string* error) const;
};

struct MapperStats {
  std::int64_t keyframe = -1;
  int points_triangulated = 0;
  int points_culled = 0, points_fused = 0, observations_added = 0, outliers_removed = 0;
  int keyframes_culled = 0, ba_keyframes = 0, ba_fixed = 0, ba_points = 0;
  bool ba_discarded = false;  ///< a loop correction moved the map while the BA was solving
  /// Another keyframe was waiting: fusion, the BA and keyframe culling were left to it.
  bool caught_up = false;
  bool ba_interrupted = false;  ///< a keyframe arrived during the BA; it kept its last iterate
  double total_ms = 0, ba_ms = 0, total_cpu_ms = 0;
};

struct FuseCounts {
  int merged = 0;    ///< duplicates merged into one point
  int attached = 0;  ///< observations added to keypoints that saw no point
};
/// Projects points `pids` into keyframe `target` and, per point, takes the best keypoint within
/// `radius_px` x its sigma (and the RGB-D chi-square gate) whose descriptor passes the fusion gate:
/// a keypoint seeing another point merges the two (the one with more observations stays), a free
/// keypoint gains the observation. Call with the map locked. Shared by mapping and loop closing.
FuseCounts fuse_into_keyframe(SlamMap& map, const CameraModel& camera, double radius_px,
                              std::int64_t target, const std::vector<std::int64_t>& pids);

class LocalMapper {
 public:
  static std::optional<LocalMapper> create(const LocalMapperOptions& options,
                                           const CameraModel& camera,
                                           std::shared_ptr<SharedMap> map, std::string* error);
  /// True while more keyframes wait for the mapper (asked between steps and after every BA
  /// iteration, so it must be cheap). Empty: never (wait and sequential modes, deterministic).
  using KeyframesWaiting = std::function<bool()>;
  /// Processes keyframe `kf_id` (already inserted by the tracker).
  MapperStats process(std::int64_t kf_id, const KeyframesWaiting& waiting = {});

 private:
  LocalMapper(LocalMapperOptions o, CameraModel c, std::shared_ptr<SharedMap> m)
      : options_(std::move(o)), camera_(c), map_(std::move(m)) {}
  int cull_points(std::int64_t kf_id);
  int triangulate(std::int64_t kf_id);
  void fuse(std::int64_t kf_id, MapperStats* stats);
  void bundle_adjust(std::int64_t kf_id, const KeyframesWaiting& waiting, MapperStats* stats);
  int cull_keyframes(std::int64_t kf_id);

  LocalMapperOptions options_;
  CameraModel camera_;
  std::shared_ptr<SharedMap> map_;
  std::vector<std::int64_t> recent_points_;
};

}  // namespace rgbdquad::slam
