// Back-end stage: keyframe selection, local loop closure (LLC), global loop closure (GLC) and
// pose-graph optimisation (thesis Sec. 3.4). It runs on whichever front-end output it is given
// (every frame in wait/sequential mode, the latest one in real-time mode).
//
// Per call: compare the frame with the most recent keyframes (recency order), decide on a new
// keyframe; VO back-end: keep the odometry prediction; LLC: clamp-correct non-keyframes towards
// the best recent keyframe; GLC: additionally test 7 spread older keyframes (+ neighbours), add a
// robust loop edge and optimise the pose graph. The matched keyframe moves to the end of the
// recency order so the following frames track against it.
//
// Not thread-safe: owned by the back-end thread (or the caller in sequential mode).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam/posegraph/posegraph.hpp"
#include "slam/thesis/frontend.hpp"
#include "slam/thesis/glc_search.hpp"
#include "slam/thesis/keyframes.hpp"
#include "slam/thesis/loop.hpp"

namespace rgbdquad::slam {

/// kVo/kLlc/kGlc: the thesis back-ends (frame-to-frame front-end). kLocalMap: tracking against a
/// local map with local mapping (tracking/, mapping/, loopclosing/), the system that flies.
enum class BackendKind { kVo, kLlc, kGlc, kLocalMap };
bool parse_backend_kind(const std::string& name, BackendKind* out, std::string* error);
const char* to_string(BackendKind kind);

struct BackendOptions {
  BackendKind kind = BackendKind::kGlc;
  KeyframeOptions keyframes;
  LoopOptions loop;
  PoseGraphOptions graph;
  MatchOptions matching;
  RansacOptions ransac;
  std::size_t min_inliers = 10;  ///< as FrontendOptions::min_inliers
  std::uint64_t seed = 20260102;
  bool is_valid(std::string* error) const;
};

struct Keyframe {
  std::int64_t id = 0;  ///< index of the frame it was made from
  double stamp_s = 0;
  RgbdFrame frame;  ///< images, for the map
  std::shared_ptr<const FrameFeatures> features;
  Eigen::Isometry3d T_odom_cam = Eigen::Isometry3d::Identity();
};

struct BackendOutput {
  std::int64_t index = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  bool keyframe = false;
  bool llc_applied = false;
  bool loop_closed = false;
  std::int64_t loop_keyframe = -1;       ///< keyframe the loop closed with
  std::int64_t reference_keyframe = -1;  ///< keyframe this pose is anchored to
  Eigen::Isometry3d T_kf_cam = Eigen::Isometry3d::Identity();
  double keyframe_ms = 0, llc_ms = 0, glc_ms = 0, posegraph_ms = 0, total_ms = 0;
  double total_cpu_ms = 0;  ///< CPU time of the calling thread
};

class BackEnd {
 public:
  static std::optional<BackEnd> create(const BackendOptions& options, std::string* error);
  BackendOutput process(const FrontendOutput& in);

  /// Current best pose of keyframe `id` (graph node), identity when unknown.
  Eigen::Isometry3d keyframe_pose(std::int64_t id) const { return graph_.pose(id); }
  const std::map<std::int64_t, Keyframe>& keyframes() const { return keyframes_; }
  const PoseGraph& graph() const { return graph_; }
  /// The graph with every node at the pose it had when inserted (before any optimisation).
  PoseGraph graph_before_optimisation() const;
  std::size_t loop_closures() const { return loop_closures_; }
  std::size_t optimisations() const { return optimisations_; }

 private:
  explicit BackEnd(BackendOptions options) : options_(std::move(options)) {}
  KeyframeMatch compare(const FrontendOutput& in, std::int64_t kf_id, std::uint64_t salt) const;
  /// The keyframes created just before and after `kf_id` (ids are frame indices, so map order).
  std::vector<std::int64_t> creation_neighbours(std::int64_t kf_id) const;
  double mean_depth_m(const FrameFeatures& f) const;
  void add_keyframe(const FrontendOutput& in, const Eigen::Isometry3d& T_world_cam,
                    const std::vector<KeyframeMatch>& recent);
  /// GLC: searches the older keyframes for a loop with frame `in`; on one, adds the loop edge,
  /// optimises the pose graph and moves `pose` to the frame's optimised pose.
  void close_global_loop(const FrontendOutput& in, const std::vector<KeyframeMatch>& recent,
                         Eigen::Isometry3d* pose, BackendOutput* out);
  void touch(std::int64_t kf_id);  ///< move to the end of the recency order

  BackendOptions options_;
  std::map<std::int64_t, Keyframe> keyframes_;
  std::vector<std::int64_t> recency_;  ///< keyframe ids, least recently used first
  std::int64_t last_created_kf_ = -1;
  PoseGraph graph_;
  std::map<std::int64_t, Eigen::Isometry3d> inserted_pose_;
  bool have_last_ = false;
  Eigen::Isometry3d last_T_world_cam_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d last_T_odom_cam_ = Eigen::Isometry3d::Identity();
  std::size_t iteration_ = 0;
  std::size_t loop_closures_ = 0;
  std::size_t optimisations_ = 0;
};

}  // namespace rgbdquad::slam
