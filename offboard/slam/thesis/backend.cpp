// Back-end: keyframes, LLC, GLC, pose graph. See backend.hpp.
#include "slam/thesis/backend.hpp"

#include <algorithm>
#include <cmath>

namespace rgbdquad::slam {

bool parse_backend_kind(const std::string& name, BackendKind* out, std::string* error) {
  if (name == "vo") {
    *out = BackendKind::kVo;
    return true;
  }
  if (name == "llc") {
    *out = BackendKind::kLlc;
    return true;
  }
  if (name == "glc") {
    *out = BackendKind::kGlc;
    return true;
  }
  if (name == "localmap") {
    *out = BackendKind::kLocalMap;
    return true;
  }
  if (error) *error = "unknown backend '" + name + "' (expected localmap, vo, llc or glc)";
  return false;
}

const char* to_string(BackendKind k) {
  switch (k) {
    case BackendKind::kVo:
      return "vo";
    case BackendKind::kLlc:
      return "llc";
    case BackendKind::kGlc:
      return "glc";
    case BackendKind::kLocalMap:
      return "localmap";
  }
  return "?";
}

bool BackendOptions::is_valid(std::string* error) const {
  if (!keyframes.is_valid(error) || !loop.is_valid(error) || !graph.is_valid(error) ||
      !matching.is_valid(error) || !ransac.is_valid(error))
    return false;
  if (min_inliers < 3) {
    if (error) *error = "backend: min_inliers must be >= 3";
    return false;
  }
  return true;
}

std::optional<BackEnd> BackEnd::create(const BackendOptions& o, std::string* error) {
  if (!o.is_valid(error)) return std::nullopt;
  return BackEnd(o);
}

double BackEnd::mean_depth_m(const FrameFeatures& f) const {
  if (f.points_cam_m.empty()) return 1.0;
  double s = 0;
  for (const auto& p : f.points_cam_m) s += p.z();
  return s / static_cast<double>(f.points_cam_m.size());
}

KeyframeMatch BackEnd::compare(const FrontendOutput& in, std::int64_t kf_id,
                               std::uint64_t salt) const {
  KeyframeMatch c;
  c.kf = kf_id;
  const Keyframe& kf = keyframes_.at(kf_id);
  const std::uint64_t seed = options_.seed ^
                             (static_cast<std::uint64_t>(in.index) * 0x9E3779B97F4A7C15ull) ^
                             (static_cast<std::uint64_t>(kf_id) * 0xC2B2AE3D27D4EB4Full) ^ salt;
  c.est = estimate_between(*in.features, *kf.features, options_.matching, options_.ransac, seed,
                           &c.matches);
  return c;
}

std::vector<std::int64_t> BackEnd::creation_neighbours(std::int64_t kf_id) const {
  std::vector<std::int64_t> out;
  auto it = keyframes_.find(kf_id);
  if (it == keyframes_.end()) return out;
  if (it != keyframes_.begin()) out.push_back(std::prev(it)->first);
  if (std::next(it) != keyframes_.end()) out.push_back(std::next(it)->first);
  return out;
}

void BackEnd::touch(std::int64_t kf_id) {
  auto it = std::find(recency_.begin(), recency_.end(), kf_id);
  if (it != recency_.end()) recency_.erase(it);
  recency_.push_back(kf_id);
}

void BackEnd::add_keyframe(const FrontendOutput& in, const Eigen::Isometry3d& T_world_cam,
                           const std::vector<KeyframeMatch>& recent) {
  Keyframe kf;
  kf.id = in.index;
  kf.stamp_s = in.stamp_s;
  kf.frame = in.frame;
  kf.features = in.features;
  kf.T_odom_cam = in.T_odom_cam;
  graph_.add_node(kf.id, T_world_cam);
  inserted_pose_[kf.id] = T_world_cam;
  const double depth = mean_depth_m(*in.features);
  // Odometry edge from the previously created keyframe: the VO chain between the two. Its
  // information is that of one frame-to-frame estimate, divided by the number of frames chained.
  if (last_created_kf_ >= 0) {
    const Keyframe& prev = keyframes_.at(last_created_kf_);
    PoseGraphEdge e;
    e.from = prev.id;
    e.to = kf.id;
    e.T_from_to = prev.T_odom_cam.inverse() * in.T_odom_cam;
    const double frames = std::max<double>(1.0, static_cast<double>(in.index - prev.id));
    e.sqrt_information =
        edge_sqrt_information(std::max<std::size_t>(in.inliers, options_.min_inliers),
                              in.rms_error_m, depth) /
        std::sqrt(frames);
    graph_.add_edge(e);
  }
  // Direct edges to the recent keyframes the frame was registered against.
  for (const KeyframeMatch& c : recent) {
    if (!c.est || c.est->inliers.size() < options_.min_inliers) continue;
    PoseGraphEdge e;
    e.from = c.kf;
    e.to = kf.id;
    e.T_from_to = c.est->T_dst_src;
    e.sqrt_information = edge_sqrt_information(c.est->inliers.size(), c.est->rms_error_m, depth);
    graph_.add_edge(e);
  }
  keyframes_.emplace(kf.id, std::move(kf));
  recency_.push_back(in.index);
  last_created_kf_ = in.index;
}

PoseGraph BackEnd::graph_before_optimisation() const {
  PoseGraph g = graph_;
  for (const auto& [id, T] : inserted_pose_) g.set_pose(id, T);
  return g;
}

void BackEnd::close_global_loop(const FrontendOutput& in, const std::vector<KeyframeMatch>& recent,
                                Eigen::Isometry3d* pose, BackendOutput* out) {
  const std::int64_t tg = steady_now_ns();
  GlcSearchInput search;
  search.frame_id = in.index;
  search.iteration = iteration_;
  search.n_features = in.features->points_cam_m.size();
  search.min_inliers = options_.min_inliers;
  search.recency = &recency_;
  for (const KeyframeMatch& r : recent) search.already_compared.push_back(r.kf);
  const std::optional<KeyframeMatch> found = search_global_loop(
      search, options_.loop,
      [&](std::int64_t kf, std::uint64_t salt) { return compare(in, kf, salt); },
      [&](std::int64_t kf) { return creation_neighbours(kf); });
  out->glc_ms = ms_since(tg);
  if (found) {
    if (!graph_.has_node(in.index)) {
      add_keyframe(in, *pose, recent);
      out->keyframe = true;
    }
    PoseGraphEdge e;
    e.from = found->kf;
    e.to = in.index;
    e.T_from_to = found->est->T_dst_src;
    e.sqrt_information = edge_sqrt_information(found->est->inliers.size(), found->est->rms_error_m,
                                               mean_depth_m(*in.features));
    e.loop = true;
    if (graph_.add_edge(e)) {
      const std::int64_t tp = steady_now_ns();
      if (graph_.optimize(options_.graph) >= 0) ++optimisations_;
      out->posegraph_ms = ms_since(tp);
      *pose = graph_.pose(in.index);
      ++loop_closures_;
      out->loop_closed = true;
      out->loop_keyframe = found->kf;
      touch(found->kf);
      touch(in.index);
    }
  }
  out->glc_ms = ms_since(tg) - out->posegraph_ms;
}

BackendOutput BackEnd::process(const FrontendOutput& in) {
  const std::int64_t t0 = steady_now_ns();
  const std::int64_t c0 = thread_cpu_now_ns();
  BackendOutput out;
  out.index = in.index;
  ++iteration_;
  // Prediction: the VO motion since the last processed frame, applied to that frame's pose.
  const Eigen::Isometry3d edge =
      have_last_ ? last_T_odom_cam_.inverse() * in.T_odom_cam : Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d pred =
      have_last_ ? last_T_world_cam_ * edge : Eigen::Isometry3d::Identity();
  Eigen::Isometry3d pose = pred;

  // 1. Compare with the most recent keyframes.
  const std::int64_t tk = steady_now_ns();
  std::vector<KeyframeMatch> recent;
  const std::size_t n_recent = std::min<std::size_t>(
      recency_.size(), static_cast<std::size_t>(options_.keyframes.recent_keyframes));
  for (std::size_t i = 0; i < n_recent; ++i)
    recent.push_back(compare(in, recency_[recency_.size() - 1 - i], 1));
  const KeyframeMatch* best = nullptr;
  for (const KeyframeMatch& c : recent)
    if (c.est && (!best || c.est->inliers.size() > best->est->inliers.size())) best = &c;
  std::optional<KeyframeEvidence> evidence;
  if (best)
    evidence = KeyframeEvidence{in.features->points_cam_m.size(), best->matches,
                                best->est->inliers.size()};
  std::optional<double> since;
  if (last_created_kf_ >= 0) since = in.stamp_s - keyframes_.at(last_created_kf_).stamp_s;
  const bool new_kf = decide_new_keyframe(options_.keyframes, since, evidence);
  out.keyframe_ms = ms_since(tk);

  // 2. Local loop closure for non-keyframes.
  const bool usable_best = best && best->est->inliers.size() >= options_.min_inliers;
  if (options_.kind != BackendKind::kVo && !new_kf && usable_best) {
    const std::int64_t tl = steady_now_ns();
    const Eigen::Isometry3d measured = graph_.pose(best->kf) * best->est->T_dst_src;
    pose = clamp_llc_correction(pred, measured, edge, options_.loop.llc_max_fraction);
    out.llc_applied = true;
    out.llc_ms = ms_since(tl);
  }
  if (new_kf) add_keyframe(in, pose, recent);

  // 3. Global loop closure.
  if (options_.kind == BackendKind::kGlc &&
      recency_.size() >
          static_cast<std::size_t>(options_.loop.glc_exclude_latest) + (new_kf ? 1 : 0))
    close_global_loop(in, recent, &pose, &out);
  out.keyframe = out.keyframe || new_kf;
  if (out.keyframe) {
    out.reference_keyframe = in.index;
  } else if (usable_best) {
    out.reference_keyframe = best->kf;
  } else if (last_created_kf_ >= 0) {
    out.reference_keyframe = last_created_kf_;
  }
  if (out.reference_keyframe >= 0)
    out.T_kf_cam = graph_.pose(out.reference_keyframe).inverse() * pose;
  out.T_world_cam = pose;
  last_T_world_cam_ = pose;
  last_T_odom_cam_ = in.T_odom_cam;
  have_last_ = true;
  out.total_ms = ms_since(t0);
  out.total_cpu_ms = (thread_cpu_now_ns() - c0) * 1e-6;
  return out;
}

}  // namespace rgbdquad::slam
