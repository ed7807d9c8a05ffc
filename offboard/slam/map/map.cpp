// Map store of the local-map SLAM; see map.hpp.
#include "slam/map/map.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace rgbdquad::slam {

double keypoint_level_scale(const cv::KeyPoint& kp, const FeatureOptions& o) {
  // Finest keypoint size each detector produces, px in the input image:
  //  ORB: size = patch size * scale factor^level, so level 0 has the patch size;
  //  SIFT (OpenCV): size = 2 sigma 2^octave; the first octave is the input resolution in our
  //  half-size mode (2 * 1.6 px) and half of that when OpenCV's upsampled octave is used;
  //  SURF: the 9x9 box filter of the first octave corresponds to a 1.2 scale, size ~ 12 px.
  double finest_px = 12.0;
  switch (o.kind) {
    case DetectorKind::kOrb:
      finest_px = o.orb_patch_size;
      break;
    case DetectorKind::kSift:
      finest_px = o.sift_upsample_first_octave ? o.sift_sigma : 2.0 * o.sift_sigma;
      break;
    case DetectorKind::kSurf:
      finest_px = 12.0;
      break;
  }
  return std::max(1.0, static_cast<double>(kp.size) / finest_px);
}

bool parse_depth_noise_model(const std::string& name, DepthNoiseModel* out, std::string* error) {
  if (name == "keypoint") {
    *out = DepthNoiseModel::kKeypointSigma;
    return true;
  }
  if (name == "kinect") {
    *out = DepthNoiseModel::kKinectAxial;
    return true;
  }
  if (name == "kinect-edge") {
    *out = DepthNoiseModel::kKinectEdge;
    return true;
  }
  if (error)
    *error = "unknown depth noise model '" + name + "' (expected keypoint, kinect or kinect-edge)";
  return false;
}

const char* to_string(DepthNoiseModel m) {
  switch (m) {
    case DepthNoiseModel::kKeypointSigma:
      return "keypoint";
    case DepthNoiseModel::kKinectAxial:
      return "kinect";
    case DepthNoiseModel::kKinectEdge:
      return "kinect-edge";
  }
  return "?";
}

double CameraModel::disparity_sigma_px(double depth_m, double kp_sigma_px,
                                       double slope_m_per_px) const {
  if (depth_noise == DepthNoiseModel::kKeypointSigma) return kp_sigma_px;
  // Nguyen et al. 2012, Eq. 1 (metres).
  constexpr double kSigmaZ0M = 0.0012, kSigmaZ2PerM2 = 0.0019, kZOffsetM = 0.4;
  const double dz = depth_m - kZOffsetM;
  double sigma_z_m = kSigmaZ0M + kSigmaZ2PerM2 * dz * dz;
  if (depth_noise == DepthNoiseModel::kKinectEdge)
    sigma_z_m = std::hypot(sigma_z_m, slope_m_per_px * kp_sigma_px);
  return std::max(kMinDisparitySigmaPx, bf_px_m * sigma_z_m / (depth_m * depth_m));
}

KeypointGrid::KeypointGrid(const std::vector<Eigen::Vector2d>& pixels, int width_px, int height_px)
    : cols_((width_px + kCellPx - 1) / kCellPx),
      rows_((height_px + kCellPx - 1) / kCellPx),
      cells_(static_cast<std::size_t>(cols_ * rows_)),
      pixels_(pixels) {
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const int cx = std::clamp(static_cast<int>(pixels[i].x() / kCellPx), 0, cols_ - 1);
    const int cy = std::clamp(static_cast<int>(pixels[i].y() / kCellPx), 0, rows_ - 1);
    cells_[static_cast<std::size_t>(cy * cols_ + cx)].push_back(static_cast<int>(i));
  }
}

void KeypointGrid::query(double u, double v, double radius_px, std::vector<int>* out) const {
  out->clear();
  if (cells_.empty() || !std::isfinite(u) || !std::isfinite(v)) return;
  const int x0 = std::max(0, static_cast<int>(std::floor((u - radius_px) / kCellPx)));
  const int x1 = std::min(cols_ - 1, static_cast<int>(std::floor((u + radius_px) / kCellPx)));
  const int y0 = std::max(0, static_cast<int>(std::floor((v - radius_px) / kCellPx)));
  const int y1 = std::min(rows_ - 1, static_cast<int>(std::floor((v + radius_px) / kCellPx)));
  const double r2 = radius_px * radius_px;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      for (int i : cells_[static_cast<std::size_t>(y * cols_ + x)]) {
        const Eigen::Vector2d d = pixels_[static_cast<std::size_t>(i)] - Eigen::Vector2d(u, v);
        if (d.squaredNorm() <= r2) out->push_back(i);
      }
}

TrackedFeatures TrackedFeatures::from(std::shared_ptr<const FrameFeatures> f,
                                      const CameraModel& cam, const FeatureOptions& options) {
  TrackedFeatures t;
  const std::size_t n = f->points_cam_m.size();
  t.pixels.reserve(n);
  t.depth_m.reserve(n);
  t.sigma_px.reserve(n);
  t.disparity_sigma_px.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d uvd = cam.project(f->points_cam_m[i]);
    t.pixels.emplace_back(uvd.x(), uvd.y());
    t.depth_m.push_back(f->points_cam_m[i].z());
    t.sigma_px.push_back(keypoint_level_scale(f->keypoints[i], options));
    // Maps saved before the slope existed load without it: axial noise only there.
    const double slope = i < f->depth_slope_m_per_px.size() ? f->depth_slope_m_per_px[i] : 0.0;
    t.disparity_sigma_px.push_back(
        cam.disparity_sigma_px(t.depth_m.back(), t.sigma_px.back(), slope));
  }
  t.grid = KeypointGrid(t.pixels, cam.width_px, cam.height_px);
  t.features = std::move(f);
  return t;
}

void SlamMap::add_keyframe(MapKeyframe kf) {
  const std::int64_t id = kf.id;
  const std::size_t n = kf.features.size() + kf.depthless.size();
  if (kf.point_ids.size() != n) kf.point_ids.assign(n, -1);
  keyframes_[id] = std::move(kf);
  ++keyframes_created_;
}

double MapKeyframe::chi2(int kp, const Eigen::Vector3d& p_world_m, const CameraModel& cam) const {
  const Eigen::Vector3d pc = T_world_cam.inverse() * p_world_m;
  if (pc.z() <= 1e-3) return 1e9;
  const auto k = static_cast<std::size_t>(kp);
  if (is_depthless(kp)) {
    const std::size_t j = k - features.size();
    return ((cam.project(pc).head<2>() - depthless.pixels[j]) / depthless.sigma_px[j])
        .squaredNorm();
  }
  return (cam.project(pc) - features.measurement(k, cam))
      .cwiseQuotient(features.sigma(k))
      .squaredNorm();
}

double MapKeyframe::chi2_bound(int kp) const {
  return is_depthless(kp) ? kChi2Mono95 : kChi2Rgbd95;
}

const MapKeyframe* SlamMap::keyframe(std::int64_t id) const {
  auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}

MapKeyframe* SlamMap::keyframe(std::int64_t id) {
  auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}

void SlamMap::cull_keyframe(std::int64_t id, std::int64_t parent) {
  auto it = keyframes_.find(id);
  if (it == keyframes_.end() || id == parent) return;
  const MapKeyframe* p = keyframe(parent);
  if (!p) return;
  culled_[id] = CulledKeyframe{parent, p->T_world_cam.inverse() * it->second.T_world_cam};
  for (std::int64_t pid : it->second.point_ids) {
    if (pid < 0) continue;
    auto pt = points_.find(pid);
    if (pt == points_.end()) continue;
    pt->second.observations.erase(id);
    if (pt->second.observations.empty()) points_.erase(pt);
  }
  keyframes_.erase(it);
}

std::optional<Eigen::Isometry3d> SlamMap::resolve_pose(std::int64_t id) const {
  Eigen::Isometry3d chain = Eigen::Isometry3d::Identity();
  // A culled keyframe's parent may itself be culled later; the chain is finite because parents
  // are always living keyframes when a keyframe is culled (bounded by the culled count).
  for (std::size_t hops = 0; hops <= culled_.size(); ++hops) {
    if (const MapKeyframe* kf = keyframe(id)) return kf->T_world_cam * chain;
    auto c = culled_.find(id);
    if (c == culled_.end()) return std::nullopt;
    chain = c->second.T_parent_kf * chain;
    id = c->second.parent;
  }
  return std::nullopt;
}

std::int64_t SlamMap::add_point(const Eigen::Vector3d& p_world_m, const cv::Mat& descriptor,
                                std::int64_t kf_id, int kp) {
  MapPoint p;
  p.id = next_point_id_++;
  p.p_world_m = p_world_m;
  p.descriptor = descriptor.clone();
  p.first_keyframe = kf_id;
  p.first_keyframe_serial = keyframes_created_;
  const std::int64_t id = p.id;
  points_[id] = std::move(p);
  add_observation(id, kf_id, kp);
  return id;
}

const MapPoint* SlamMap::point(std::int64_t id) const {
  auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}

MapPoint* SlamMap::point(std::int64_t id) {
  auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}

void SlamMap::add_observation(std::int64_t pid, std::int64_t kf_id, int kp) {
  MapPoint* p = point(pid);
  MapKeyframe* kf = keyframe(kf_id);
  if (!p || !kf || kp < 0 || static_cast<std::size_t>(kp) >= kf->point_ids.size()) return;
  const std::int64_t old = kf->point_ids[static_cast<std::size_t>(kp)];
  if (old >= 0 && old != pid) erase_observation(old, kf_id);
  auto prev = p->observations.find(kf_id);
  if (prev != p->observations.end() && prev->second != kp)
    kf->point_ids[static_cast<std::size_t>(prev->second)] = -1;
  p->observations[kf_id] = kp;
  kf->point_ids[static_cast<std::size_t>(kp)] = pid;
}

void SlamMap::erase_observation(std::int64_t pid, std::int64_t kf_id) {
  MapPoint* p = point(pid);
  if (!p) return;
  auto it = p->observations.find(kf_id);
  if (it == p->observations.end()) return;
  if (MapKeyframe* kf = keyframe(kf_id)) {
    auto& slot = kf->point_ids[static_cast<std::size_t>(it->second)];
    if (slot == pid) slot = -1;
  }
  p->observations.erase(it);
  if (p->observations.empty()) points_.erase(pid);
}

void SlamMap::erase_point(std::int64_t pid) {
  MapPoint* p = point(pid);
  if (!p) return;
  for (const auto& [kf_id, kp] : p->observations) {
    if (MapKeyframe* kf = keyframe(kf_id)) {
      auto& slot = kf->point_ids[static_cast<std::size_t>(kp)];
      if (slot == pid) slot = -1;
    }
  }
  points_.erase(pid);
}

void SlamMap::replace_point(std::int64_t from, std::int64_t into) {
  if (from == into) return;
  MapPoint* a = point(from);
  MapPoint* b = point(into);
  if (!a || !b) return;
  const auto obs = a->observations;
  const int visible = a->visible, found = a->found;
  erase_point(from);
  b = point(into);
  for (const auto& [kf_id, kp] : obs) {
    if (b->observations.count(kf_id)) continue;
    add_observation(into, kf_id, kp);
  }
  b->visible += visible;
  b->found += found;
}

std::vector<std::pair<std::int64_t, int>> SlamMap::covisible(std::int64_t kf_id,
                                                             int min_shared) const {
  std::vector<std::pair<std::int64_t, int>> out;
  const MapKeyframe* kf = keyframe(kf_id);
  if (!kf) return out;
  std::unordered_map<std::int64_t, int> shared;
  for (std::int64_t pid : kf->point_ids) {
    if (pid < 0) continue;
    const MapPoint* p = point(pid);
    if (!p) continue;
    for (const auto& [other, kp] : p->observations)
      if (other != kf_id) ++shared[other];
  }
  for (const auto& [other, n] : shared)
    if (n >= min_shared) out.emplace_back(other, n);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first < b.first;
  });
  return out;
}

int SlamMap::tracked_points(std::int64_t kf_id, int min_obs) const {
  const MapKeyframe* kf = keyframe(kf_id);
  if (!kf) return 0;
  int n = 0;
  for (std::int64_t pid : kf->point_ids) {
    if (pid < 0) continue;
    const MapPoint* p = point(pid);
    if (p && static_cast<int>(p->observations.size()) >= min_obs) ++n;
  }
  return n;
}

bool SlamMap::in_loop_edge(std::int64_t kf_id) const {
  return std::any_of(loop_edges_.begin(), loop_edges_.end(),
                     [&](const LoopEdge& e) { return e.a == kf_id || e.b == kf_id; });
}

void SlamMap::restore(std::map<std::int64_t, MapKeyframe> kfs, std::map<std::int64_t, MapPoint> pts,
                      std::map<std::int64_t, CulledKeyframe> culled,
                      std::vector<LoopEdge> loop_edges) {
  keyframes_ = std::move(kfs);
  points_ = std::move(pts);
  culled_ = std::move(culled);
  loop_edges_ = std::move(loop_edges);
  next_point_id_ = points_.empty() ? 0 : points_.rbegin()->first + 1;
  keyframes_created_ = static_cast<std::int64_t>(keyframes_.size() + culled_.size());
}

}  // namespace rgbdquad::slam
