// Loop closing: runs once per mapped keyframe on its own thread, off the camera-to-command path
// (ORB-SLAM2's LoopClosing, for RGB-D: rigid SE(3), no scale). Steps:
//  1. the keyframe's bag-of-words vector (vocabulary.hpp) goes into the keyframe database;
//  2. detection: the database is queried for keyframes scoring at least as well as the keyframe's
//     own weakest covisible neighbour (ORB-SLAM2's minScore), excluding the keyframes connected to
//     it in the covisibility graph (>= 15 shared points, ORB-SLAM2's GetConnectedKeyFrames: those
//     the local map already ties to it), best few first;
//  3. temporal consistency (loop/loop_consistency.hpp, ORB-SLAM2 DetectLoop): only candidates
//     whose covisibility group continues groups found for the 3 keyframes before are verified;
//  4. geometric verification per candidate: descriptor matches against the candidate's points and
//     3D-3D RANSAC (registration.hpp), then a two-pass projection fit against the candidate and its
//     covisible neighbours' points; accepted with >= min_projection_inliers inliers;
//  5. odometry consistency (loop/loop_consistency.hpp, Kimera-RPGO / PCM): the verified relative
//     pose must agree with the map's own relative pose of the two keyframes within a chi-square
//     bound on the drift the map's covisibility chain between them can have accumulated - an
//     identical-looking but different place (a repeated tile, a second door) is refused here;
//  6. essential-graph optimisation with Ceres (posegraph/): all keyframes; spanning-tree edges
//  (each
//     keyframe to its most covisible older keyframe), strong covisibility edges (>= 100 shared
//     points) with identity information, and every loop edge so far weighted as the 1 + 10
//     keyframe-pair links it stands for (ORB-SLAM2's loop connections), plus a gravity factor per
//     keyframe that measured gravity; the first keyframe (world frame) held fixed; solved on a
//     snapshot, without the map lock;
//  7. correction in one short step under the map lock: each keyframe is moved by its own pose-graph
//     correction (applied to its current pose, so mapping done meanwhile is kept), each point with
//     its first keyframe; SharedMap::corrections is bumped (the tracker re-anchors, a bundle
//     adjustment in flight is dropped); then, in a second short step, the loop side's points are
//     fused into the keyframe and its neighbours (duplicates across the loop merged).
// No global bundle adjustment afterwards: the next local BAs refine the corrected windows, and a
// global BA over the whole map would be the one step whose cost grows with the flight.
//
// Thread safety: one LoopCloser; it locks the shared map only for copies and the two write steps,
// whose hold times it reports (LoopStats).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam/loopclosing/keyframe_database.hpp"
#include "slam/loopclosing/loop_consistency.hpp"
#include "slam/posegraph/posegraph.hpp"
#include "slam/tracking/registration.hpp"
#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

struct LoopCloserOptions {
  int min_keyframes_in_map =
      10;  ///< ORB-SLAM2 DetectLoop: no search while the map has < 10 keyframes
  int keyframes_between_loops = 10;  ///< ORB-SLAM2: 10 keyframes after a loop before the next
  int covisibility_min_shared =
      15;                          ///< ORB-SLAM2's covisibility edge: neighbours that set minScore
  std::size_t max_candidates = 3;  ///< verified per keyframe, best score first (bounds the cost)
  MatchOptions matching;           ///< descriptor matching for verification (as relocalisation)
  RansacOptions ransac;            ///< 3D-3D RANSAC (thesis values, as relocalisation)
  int min_ransac_inliers = 20;     ///< ORB-SLAM2 ComputeSim3: 20 RANSAC inliers
  ProjectionFitOptions fit;        ///< the tracker's projection settings
  double fit_first_radius_px = 10.0;  ///< ORB-SLAM2 ComputeSim3 SearchByProjection th = 10
  int min_projection_inliers = 40;    ///< ORB-SLAM2 ComputeSim3: >= 40 matches after projection
  int loop_neighbours = 10;  ///< candidate's (and keyframe's) best covisible keyframes used
  int strong_covisibility =
      100;  ///< ORB-SLAM2 essential graph: covisibility edges with >= 100 points
  double fuse_radius_px = 4.0;  ///< ORB-SLAM2 SearchAndFuse th = 4
  PoseGraphOptions posegraph;   ///< Ceres; max_iterations 20 as ORB-SLAM2's essential graph
  /// The rotation sigma the graph's unit-information edges stand for, to weigh the keyframes'
  /// gravity factors (when the tracker measures gravity) against them: the tracked rotation
  /// between consecutive frames is within about 0.4 deg rms of the mocap's on fr1_xyz_first300
  /// (ours and ORB-SLAM2's alike, mocap noise included), so 0.5 deg per edge. A 3 deg
  /// accelerometer sample then counts 1/36 of an edge: gravity holds the tilt the chain of edges
  /// leaves free without bending their shape.
  double posegraph_edge_rotation_sigma_rad = 0.5 * M_PI / 180.0;
  /// ORB-SLAM2's temporal consistency (off only for ablations and the tests that show it matters):
  /// a candidate is verified only when its covisibility group continues groups found for the
  /// previous `consistent_keyframes` keyframes.
  bool temporal_consistency = true;
  int consistent_keyframes = CovisibilityConsistency::kOrbSlam2ConsecutiveKeyframes;
  /// The odometry-consistency gate on a verified loop (off only for ablations and tests).
  bool odometry_gate = true;
  DriftModel drift;  ///< measured drift per metre of the map's chain (loop_consistency.hpp)
  LoopCloserOptions() { posegraph.max_iterations = 20; }
  bool is_valid(std::string* error) const;
};

struct LoopStats {
  std::int64_t keyframe = -1;
  bool searched = false;     ///< the map was big enough and no loop closed recently
  int candidates = 0;        ///< database hits
  int consistent = 0;        ///< hits that passed temporal consistency (passed to verification)
  int verified_ransac = 0;   ///< candidates whose RANSAC reached min_ransac_inliers
  int verified_fit = 0;      ///< candidates that also reached min_projection_inliers
  int refused_odometry = 0;  ///< verified candidates refused by the odometry-consistency gate
  /// The gate's numbers for the last candidate it judged (accepted or refused).
  std::int64_t gate_keyframe = -1;
  double gate_path_m = 0, gate_translation_m = 0, gate_rotation_deg = 0, gate_chi2 = 0;
  bool accepted = false;
  std::int64_t loop_keyframe = -1;
  int ransac_inliers = 0, fit_inliers = 0;
  double correction_m = 0, correction_deg = 0;  ///< how far the keyframe moved
  int graph_keyframes = 0, graph_edges = 0;
  int points_merged = 0, points_attached = 0;
  double bow_ms = 0, query_ms = 0, verify_ms = 0, posegraph_ms = 0;
  double snapshot_lock_ms = 0, apply_lock_ms = 0, fuse_lock_ms = 0;  ///< map lock hold times
  double total_ms = 0, total_cpu_ms = 0;
};

class LoopCloser {
 public:
  static std::optional<LoopCloser> create(const LoopCloserOptions& options,
                                          const CameraModel& camera, std::shared_ptr<SharedMap> map,
                                          std::shared_ptr<const BinaryVocabulary> vocabulary,
                                          std::string* error);
  /// Processes keyframe `kf_id` (already mapped): detect(), then optimise() and apply() when a loop
  /// is verified. A keyframe culled meanwhile is skipped.
  LoopStats process(std::int64_t kf_id);

  /// A verified loop: keyframe `keyframe` seen from the loop side (candidate) at T_world_kf.
  struct Loop {
    std::int64_t keyframe = -1, candidate = -1;
    Eigen::Isometry3d T_world_kf = Eigen::Isometry3d::Identity();
    std::vector<std::int64_t>
        loop_points;  ///< the candidate side's points (fused after the correction)
  };
  /// The pose-graph result: per keyframe of the snapshot, the correction to apply (world-side
  /// delta).
  struct Correction {
    Loop loop;
    LoopEdge edge;
    std::map<std::int64_t, Eigen::Isometry3d> delta;
  };
  // The phases of process(), public so that tests can run tracking between them.
  /// Adds the keyframe to the database and verifies the best candidates (short map locks).
  std::optional<Loop> detect(std::int64_t kf_id, LoopStats* stats);
  /// Essential-graph optimisation on a snapshot; the solve runs without the map lock.
  std::optional<Correction> optimise(const Loop& loop, LoopStats* stats) const;
  /// Moves keyframes and points (one lock hold), then fuses the loop (one hold per keyframe).
  void apply(const Correction& correction, LoopStats* stats);
  /// Adds every keyframe of the map to the database (after a map load).
  void index_map();
  const KeyframeDatabase& database() const { return database_; }

 private:
  LoopCloser(LoopCloserOptions o, CameraModel c, std::shared_ptr<SharedMap> m,
             std::shared_ptr<const BinaryVocabulary> v)
      : options_(std::move(o)),
        camera_(c),
        map_(std::move(m)),
        vocabulary_(std::move(v)),
        consistency_(options_.consistent_keyframes) {}
  std::optional<Loop> verify(const TrackedFeatures& frame,
                             const std::vector<std::int64_t>& candidates, std::int64_t kf_id,
                             LoopStats* stats) const;

  LoopCloserOptions options_;
  CameraModel camera_;
  std::shared_ptr<SharedMap> map_;
  std::shared_ptr<const BinaryVocabulary> vocabulary_;
  /// The odometry-consistency gate for a verified loop (takes the map lock for a snapshot).
  OdometryConsistency odometry_consistency(std::int64_t kf_id, std::int64_t candidate,
                                           const Eigen::Isometry3d& T_world_kf_loop) const;

  KeyframeDatabase database_;
  CovisibilityConsistency consistency_;
  std::int64_t processed_ = 0;
  std::int64_t last_loop_at_ = -1000000;  ///< `processed_` when the last loop closed
};

}  // namespace rgbdquad::slam
