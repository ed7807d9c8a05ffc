// Loop closing; see loop_closer.hpp.
#include "slam/loopclosing/loop_closer.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <unordered_set>

#include "slam/mapping/local_mapper.hpp"

namespace rgbdquad::slam {

bool LoopCloserOptions::is_valid(std::string* error) const {
  auto fail = [&](const char* m) {
    if (error) *error = std::string("loop closer: ") + m;
    return false;
  };
  if (min_keyframes_in_map < 2 || keyframes_between_loops < 0)
    return fail("keyframe counts out of range");
  if (covisibility_min_shared < 1 || strong_covisibility < 1 || loop_neighbours < 0)
    return fail("covisibility counts must be positive");
  if (max_candidates < 1) return fail("max_candidates must be >= 1");
  if (min_ransac_inliers < 3 || min_projection_inliers < 6) return fail("inlier bars too low");
  if (!(fit_first_radius_px > 0) || !(fuse_radius_px > 0)) return fail("radii must be positive");
  if (consistent_keyframes < 0) return fail("consistent_keyframes must be >= 0");
  if (!(posegraph_edge_rotation_sigma_rad > 0))
    return fail("posegraph_edge_rotation_sigma_rad must be positive");
  return drift.is_valid(error) && matching.is_valid(error) && ransac.is_valid(error) &&
         posegraph.is_valid(error);
}

std::optional<LoopCloser> LoopCloser::create(const LoopCloserOptions& options,
                                             const CameraModel& camera,
                                             std::shared_ptr<SharedMap> map,
                                             std::shared_ptr<const BinaryVocabulary> vocabulary,
                                             std::string* error) {
  if (!options.is_valid(error)) return std::nullopt;
  if (!map || !vocabulary) {
    if (error) *error = "loop closer: no map or no vocabulary";
    return std::nullopt;
  }
  return LoopCloser(options, camera, std::move(map), std::move(vocabulary));
}

void LoopCloser::index_map() {
  std::vector<std::pair<std::int64_t, std::shared_ptr<const FrameFeatures>>> kfs;
  {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    for (const auto& [id, kf] : map_->map.keyframes()) kfs.emplace_back(id, kf.features.features);
  }
  for (const auto& [id, f] : kfs) database_.add(id, vocabulary_->transform(f->descriptors));
}

LoopStats LoopCloser::process(std::int64_t kf_id) {
  const std::int64_t t0 = steady_now_ns();
  const std::int64_t c0 = thread_cpu_now_ns();
  LoopStats stats;
  stats.keyframe = kf_id;
  if (const auto loop = detect(kf_id, &stats))
    if (const auto correction = optimise(*loop, &stats)) apply(*correction, &stats);
  stats.total_ms = ms_since(t0);
  stats.total_cpu_ms = (thread_cpu_now_ns() - c0) * 1e-6;
  return stats;
}

std::optional<LoopCloser::Loop> LoopCloser::detect(std::int64_t kf_id, LoopStats* out) {
  LoopStats& stats = *out;
  TrackedFeatures tf;
  std::vector<std::pair<std::int64_t, int>> cov;
  std::size_t keyframes = 0;
  std::vector<std::int64_t> gone;
  {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const std::int64_t l0 = steady_now_ns();
    const MapKeyframe* kf = map_->map.keyframe(kf_id);
    if (!kf) return std::nullopt;
    tf = kf->features;
    cov = map_->map.covisible(kf_id, 1);
    keyframes = map_->map.keyframes().size();
    for (std::int64_t id : database_.ids())
      if (!map_->map.has_keyframe(id)) gone.push_back(id);
    stats.snapshot_lock_ms = ms_since(l0);
  }
  for (std::int64_t id : gone) database_.erase(id);  // culled keyframes leave the database
  ++processed_;
  std::int64_t t = steady_now_ns();
  BowVector bow = vocabulary_->transform(tf.features->descriptors);
  stats.bow_ms = ms_since(t);
  // ORB-SLAM2's bar: a candidate must look at least as similar as the least similar of the
  // keyframe's covisible neighbours (sorted by shared points, so the strong ones come first).
  double min_score = 1.0;
  bool have_neighbour = false;
  std::set<std::int64_t> excluded{kf_id};
  for (const auto& [n, shared] : cov) {
    if (shared < options_.covisibility_min_shared) continue;
    excluded.insert(
        n);  // connected in the covisibility graph: not a loop (ORB-SLAM2 DetectLoopCandidates)
    if (const BowVector* v = database_.vector(n)) {
      min_score = std::min(min_score, bow_score(bow, *v));
      have_neighbour = true;
    }
  }
  t = steady_now_ns();
  stats.searched = have_neighbour && static_cast<int>(keyframes) >= options_.min_keyframes_in_map &&
                   processed_ - last_loop_at_ > options_.keyframes_between_loops;
  std::vector<KeyframeDatabase::Hit> hits;
  if (stats.searched) hits = database_.query(bow, excluded, min_score, options_.max_candidates);
  database_.add(kf_id, std::move(bow));
  stats.query_ms = ms_since(t);
  stats.candidates = static_cast<int>(hits.size());
  if (!stats.searched) return std::nullopt;  // ORB-SLAM2: no search leaves the chains untouched
  // Temporal consistency: each hit stands for its covisibility group (the candidate and its
  // connected keyframes); only hits continuing a chain of groups found for the previous keyframes
  // go on to verification. No hit ends every chain.
  std::vector<std::set<std::int64_t>> groups;
  if (!hits.empty()) {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const std::int64_t l0 = steady_now_ns();
    for (const auto& h : hits) {
      std::set<std::int64_t> g{h.keyframe};
      for (const auto& [n, shared] :
           map_->map.covisible(h.keyframe, options_.covisibility_min_shared))
        g.insert(n);
      groups.push_back(std::move(g));
    }
    stats.snapshot_lock_ms += ms_since(l0);
  }
  const std::vector<std::size_t> consistent = consistency_.update(groups);
  std::vector<std::int64_t> candidates;
  if (options_.temporal_consistency) {
    for (std::size_t i : consistent) candidates.push_back(hits[i].keyframe);
  } else {
    for (const auto& h : hits) candidates.push_back(h.keyframe);
  }
  stats.consistent = static_cast<int>(candidates.size());
  if (candidates.empty()) return std::nullopt;
  t = steady_now_ns();
  auto loop = verify(tf, candidates, kf_id, &stats);
  stats.verify_ms = ms_since(t);
  return loop;
}

std::optional<LoopCloser::Loop> LoopCloser::verify(const TrackedFeatures& frame,
                                                   const std::vector<std::int64_t>& candidates,
                                                   std::int64_t kf_id, LoopStats* stats) const {
  for (std::int64_t cand : candidates) {
    KeyframePoints kp;
    std::vector<LocalPoint> local;
    {
      const auto lock = map_->lock(MapParty::kLoopClosing);
      const SlamMap& map = map_->map;
      kp = keyframe_points(map, cand);
      if (kp.keyframe < 0) continue;
      std::vector<std::int64_t> side{cand};
      const auto cov = map.covisible(cand, 1);
      for (std::size_t i = 0; i < cov.size() && static_cast<int>(i) < options_.loop_neighbours; ++i)
        side.push_back(cov[i].first);
      std::unordered_set<std::int64_t> seen;
      for (std::int64_t k : side)
        for (std::int64_t pid : map.keyframe(k)->point_ids)
          if (pid >= 0 && seen.insert(pid).second)
            if (const MapPoint* p = map.point(pid))
              local.push_back(LocalPoint{pid, p->p_world_m, p->descriptor});
    }
    const std::uint64_t seed = 0x9E3779B97F4A7C15ull ^ static_cast<std::uint64_t>(kf_id) ^
                               (static_cast<std::uint64_t>(cand) << 32);
    const auto reg = register_to_keyframe(*frame.features, kp, options_.matching, options_.ransac,
                                          seed, options_.min_ransac_inliers);
    if (!reg) continue;
    ++stats->verified_ransac;
    const ProjectionFit fit = fit_by_projection(local, frame, camera_, reg->T_world_cam.inverse(),
                                                options_.fit_first_radius_px, options_.fit);
    if (!fit.ok || static_cast<int>(fit.inliers) < options_.min_projection_inliers ||
        !fit.T_cam_world.matrix().allFinite())
      continue;
    ++stats->verified_fit;
    if (options_.odometry_gate) {
      const OdometryConsistency gate = odometry_consistency(kf_id, cand, fit.T_cam_world.inverse());
      stats->gate_keyframe = cand;
      stats->gate_path_m = gate.path_m;
      stats->gate_translation_m = gate.translation_m;
      stats->gate_rotation_deg = gate.rotation_deg;
      stats->gate_chi2 = gate.chi2;
      if (!gate.consistent) {
        ++stats->refused_odometry;
        continue;
      }
    }
    Loop v;
    v.keyframe = kf_id;
    v.candidate = cand;
    v.T_world_kf = fit.T_cam_world.inverse();
    for (const LocalPoint& p : local) v.loop_points.push_back(p.id);
    stats->ransac_inliers = static_cast<int>(reg->inliers);
    stats->fit_inliers = static_cast<int>(fit.inliers);
    return v;
  }
  return std::nullopt;
}

OdometryConsistency LoopCloser::odometry_consistency(
    std::int64_t kf_id, std::int64_t candidate, const Eigen::Isometry3d& T_world_kf_loop) const {
  KeyframeGraph graph;
  Eigen::Isometry3d T_world_cand = Eigen::Isometry3d::Identity(),
                    T_world_kf = Eigen::Isometry3d::Identity();
  double chain_m = 0;  // fallback: the keyframes in creation order between the two
  {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const SlamMap& map = map_->map;
    const MapKeyframe* a = map.keyframe(candidate);
    const MapKeyframe* b = map.keyframe(kf_id);
    if (!a || !b) return OdometryConsistency{};  // culled meanwhile: not consistent
    T_world_cand = a->T_world_cam;
    T_world_kf = b->T_world_cam;
    const MapKeyframe* previous = nullptr;
    for (const auto& [id, kf] : map.keyframes()) {
      graph.position_m[id] = kf.T_world_cam.translation();
      for (const auto& [n, shared] : map.covisible(id, options_.covisibility_min_shared))
        if (n < id) graph.add_edge(n, id);
      if (id >= std::min(candidate, kf_id) && id <= std::max(candidate, kf_id)) {
        if (previous)
          chain_m += (kf.T_world_cam.translation() - previous->T_world_cam.translation()).norm();
        previous = &kf;
      }
    }
  }
  const double path_m = map_path_length_m(graph, candidate, kf_id).value_or(chain_m);
  return check_odometry_consistency(T_world_cand.inverse() * T_world_kf,
                                    T_world_cand.inverse() * T_world_kf_loop,
                                    std::min(path_m, chain_m), options_.drift);
}

std::optional<LoopCloser::Correction> LoopCloser::optimise(const Loop& loop,
                                                           LoopStats* stats) const {
  const std::int64_t kf_id = loop.keyframe;
  // Snapshot: poses and the essential graph's edges.
  std::map<std::int64_t, Eigen::Isometry3d> poses;
  std::vector<PoseGraphEdge> edges;
  std::vector<LoopEdge> loops;
  std::vector<PoseGraphGravity> gravity;
  {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const std::int64_t l0 = steady_now_ns();
    const SlamMap& map = map_->map;
    if (!map.has_keyframe(kf_id) || !map.has_keyframe(loop.candidate)) return std::nullopt;
    for (const auto& [id, kf] : map.keyframes()) {
      poses[id] = kf.T_world_cam;
      if (!kf.gravity || !map_->gravity_down_world) continue;
      // In the graph's units: the measurement's sigma over the rotation sigma of an edge.
      GravityObservation g = *kf.gravity;
      g.sigma_rad /= options_.posegraph_edge_rotation_sigma_rad;
      gravity.push_back(PoseGraphGravity{id, *map_->gravity_down_world, g});
    }
    std::int64_t previous = -1;
    for (const auto& [id, kf] : map.keyframes()) {
      const auto cov = map.covisible(id, 1);
      std::int64_t parent = -1;
      for (const auto& [n, shared] : cov)  // most shared first: the spanning-tree parent
        if (n < id) {
          parent = n;
          break;
        }
      if (parent < 0) parent = previous;  // keeps the graph connected where covisibility is not
      if (parent >= 0)
        edges.push_back(PoseGraphEdge{parent, id, Eigen::Isometry3d::Identity(), {}, false});
      for (const auto& [n, shared] : cov) {
        if (shared < options_.strong_covisibility) break;
        if (n < id && n != parent)
          edges.push_back(PoseGraphEdge{n, id, Eigen::Isometry3d::Identity(), {}, false});
      }
      previous = id;
    }
    loops = map.loop_edges();
    stats->snapshot_lock_ms += ms_since(l0);
  }
  const LoopEdge fresh{loop.candidate, kf_id, poses.at(loop.candidate).inverse() * loop.T_world_kf};
  loops.push_back(fresh);
  const std::int64_t t0 = steady_now_ns();
  PoseGraph graph;
  for (const auto& [id, T] : poses)
    graph.add_node(id, T);  // the first (oldest) keyframe is held fixed
  // Identity information on every edge, as ORB-SLAM2's essential graph: odometry-like edges keep
  // the current relative poses, loop edges pull the two sides together.
  for (PoseGraphEdge& e : edges) {
    e.T_from_to = poses.at(e.from).inverse() * poses.at(e.to);
    e.sqrt_information.setOnes();
    graph.add_edge(e);
  }
  // A loop edge stands for the links between the keyframe's neighbourhood and the loop side
  // (ORB-SLAM2 adds one edge per pair of those keyframes, each with identity information): weighted
  // as 1 + loop_neighbours such edges, the loop keyframe lands at its verified pose and the drift
  // is spread over the chain between the two sides.
  const double loop_weight = std::sqrt(1.0 + options_.loop_neighbours);
  for (const LoopEdge& l : loops) {
    if (!poses.count(l.a) || !poses.count(l.b)) continue;
    PoseGraphEdge e{l.a, l.b, l.T_a_b, {}, true};
    e.sqrt_information.setConstant(loop_weight);
    graph.add_edge(e);
  }
  for (const PoseGraphGravity& g : gravity) graph.add_gravity(g);
  stats->graph_keyframes = static_cast<int>(poses.size());
  stats->graph_edges = static_cast<int>(graph.edges().size());
  const double cost = graph.optimize(options_.posegraph);
  stats->posegraph_ms = ms_since(t0);
  if (!(cost >= 0)) return std::nullopt;
  Correction c;
  c.loop = loop;
  c.edge = fresh;
  for (const auto& [id, T_old] : poses) {
    const Eigen::Isometry3d d = graph.pose(id) * T_old.inverse();
    if (!d.matrix().allFinite()) return std::nullopt;
    c.delta[id] = d;
  }
  return c;
}

void LoopCloser::apply(const Correction& c, LoopStats* stats) {
  const Loop& loop = c.loop;
  const std::int64_t kf_id = loop.keyframe;
  const auto& delta = c.delta;
  const Eigen::Isometry3d d_loop =
      delta.count(kf_id) ? delta.at(kf_id) : Eigen::Isometry3d::Identity();
  // One short step under the lock: move keyframes and points, record the loop.
  {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const std::int64_t l0 = steady_now_ns();
    SlamMap& map = map_->map;
    auto delta_of = [&](std::int64_t kf) -> const Eigen::Isometry3d* {
      auto it = delta.find(kf);
      return it == delta.end() ? nullptr : &it->second;
    };
    std::vector<std::int64_t> ids;
    for (const auto& [id, kf] : map.keyframes()) ids.push_back(id);
    for (std::int64_t id : ids) {
      const Eigen::Isometry3d* d = delta_of(id);
      MapKeyframe* kf = map.keyframe(id);
      kf->T_world_cam =
          (d ? *d : d_loop) * kf->T_world_cam;  // newer than the snapshot: with the loop keyframe
    }
    std::vector<std::int64_t> pids;
    for (const auto& [pid, p] : map.points()) pids.push_back(pid);
    for (std::int64_t pid : pids) {
      MapPoint* p = map.point(pid);
      const Eigen::Isometry3d* d = delta_of(p->first_keyframe);
      for (auto it = p->observations.begin(); !d && it != p->observations.end(); ++it)
        d = delta_of(it->first);
      p->p_world_m = (d ? *d : d_loop) * p->p_world_m;
    }
    if (map.has_keyframe(loop.candidate) && map.has_keyframe(kf_id)) map.add_loop_edge(c.edge);
    ++map_->corrections;
    stats->apply_lock_ms = ms_since(l0);
  }
  stats->accepted = true;
  stats->loop_keyframe = loop.candidate;
  stats->correction_m = d_loop.translation().norm();
  stats->correction_deg = Eigen::AngleAxisd(d_loop.rotation()).angle() * 180.0 / M_PI;
  last_loop_at_ = processed_;
  consistency_.reset();  // the chains described the map before the correction
  // Fuse the loop side's points into the keyframe and its neighbours, one keyframe per lock hold.
  std::vector<std::int64_t> targets{kf_id};
  {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const auto cov = map_->map.covisible(kf_id, 1);
    for (std::size_t i = 0; i < cov.size() && static_cast<int>(i) < options_.loop_neighbours; ++i)
      targets.push_back(cov[i].first);
  }
  for (std::int64_t target : targets) {
    const auto lock = map_->lock(MapParty::kLoopClosing);
    const std::int64_t l0 = steady_now_ns();
    const FuseCounts c =
        fuse_into_keyframe(map_->map, camera_, options_.fuse_radius_px, target, loop.loop_points);
    stats->points_merged += c.merged;
    stats->points_attached += c.attached;
    stats->fuse_lock_ms = std::max(stats->fuse_lock_ms, ms_since(l0));
  }
}

}  // namespace rgbdquad::slam
