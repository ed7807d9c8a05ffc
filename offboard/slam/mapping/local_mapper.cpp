// Local mapping; see local_mapper.hpp.
#include "slam/mapping/local_mapper.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <limits>
#include <unordered_map>
#include <unordered_set>

#include "slam/mapping/rgbd_reprojection_cost.hpp"
#include "slam/matching/matching.hpp"
#include "slam/tracking/projection_search.hpp"

namespace rgbdquad::slam {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

/// Gravity factor of one keyframe (slam/core/types.hpp gravity_residual) on its rotation block.
struct GravityCost {
  GravityCost(const Eigen::Vector3d& down_world, const GravityObservation& g)
      : down_world_(down_world), g_(g) {}
  template <typename T>
  bool operator()(const T* rotation, T* residual) const {
    const T d_w[3] = {T(down_world_.x()), T(down_world_.y()), T(down_world_.z())};
    T d_c[3];
    ceres::AngleAxisRotatePoint(rotation, d_w, d_c);
    gravity_residual(d_c, g_, residual);
    return true;
  }
  Eigen::Vector3d down_world_;
  GravityObservation g_;
};

std::array<double, 6> to_block(const Eigen::Isometry3d& T_cam_world) {
  const Eigen::AngleAxisd aa(T_cam_world.rotation());
  const Eigen::Vector3d w = aa.axis() * aa.angle();
  const Eigen::Vector3d t = T_cam_world.translation();
  return {w.x(), w.y(), w.z(), t.x(), t.y(), t.z()};
}

Eigen::Isometry3d from_block(const std::array<double, 6>& b) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d w(b[0], b[1], b[2]);
  const double angle = w.norm();
  if (angle > 1e-12) T.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  T.translation() = Eigen::Vector3d(b[3], b[4], b[5]);
  return T;
}

}  // namespace

FuseCounts fuse_into_keyframe(SlamMap& map, const CameraModel& camera, double radius_px,
                              std::int64_t target, const std::vector<std::int64_t>& pids) {
  FuseCounts counts;
  const MapKeyframe* kf = map.keyframe(target);
  if (!kf) return counts;
  const Eigen::Isometry3d T_cam_world = kf->T_world_cam.inverse();
  const cv::Mat& desc = kf->features.features->descriptors;
  const bool binary = desc.type() == CV_8U;
  std::vector<int> cand;
  for (std::int64_t pid : pids) {
    const MapPoint* p = map.point(pid);
    if (!p || p->observations.count(target)) continue;
    const Eigen::Vector3d pc = T_cam_world * p->p_world_m;
    if (pc.z() <= 0.1) continue;
    const Eigen::Vector3d uvd = camera.project(pc);
    if (!camera.in_image(uvd.x(), uvd.y())) continue;
    kf->features.grid.query(uvd.x(), uvd.y(), radius_px * 8.0, &cand);
    double best = 1e300;
    int best_k = -1;
    for (int k : cand) {
      const auto ks = static_cast<std::size_t>(k);
      const Eigen::Vector3d e =
          (uvd - kf->features.measurement(ks, camera)).cwiseQuotient(kf->features.sigma(ks));
      if (e.head<2>().norm() > radius_px || e.squaredNorm() > kChi2Rgbd95) continue;
      const double d = descriptor_distance(p->descriptor, desc.row(k));
      if (d < best) {
        best = d;
        best_k = k;
      }
    }
    if (best_k < 0) continue;
    // Fusion gate: ORB-SLAM2 TH_LOW (50 bits) for binary; NNMMT for float descriptors.
    const double gate = binary ? 50.0 : 0.5 * distance_to_origin(desc.row(best_k));
    if (best > gate) continue;
    const std::int64_t there = kf->point_ids[static_cast<std::size_t>(best_k)];
    if (there >= 0 && there != pid) {
      const MapPoint* q = map.point(there);
      if (!q) continue;
      // Keep the point with more observations (ties: the older one).
      const bool keep_q = q->observations.size() > p->observations.size() ||
                          (q->observations.size() == p->observations.size() && there < pid);
      if (keep_q)
        map.replace_point(pid, there);
      else
        map.replace_point(there, pid);
      ++counts.merged;
    } else if (there < 0) {
      map.add_observation(pid, target, best_k);
      ++counts.attached;
    }
    kf = map.keyframe(target);
    if (!kf) return counts;
  }
  return counts;
}

bool LocalMapperOptions::is_valid(std::string* error) const {
  auto fail = [&](const char* m) {
    if (error) *error = std::string("local mapper: ") + m;
    return false;
  };
  if (!(min_found_ratio >= 0 && min_found_ratio < 1))
    return fail("min_found_ratio must be in [0, 1)");
  if (cull_after_keyframes < 1 || min_observing_keyframes < 1)
    return fail("culling counts must be >= 1");
  if (fuse_neighbours < 0 || !(fuse_radius_px > 0)) return fail("fuse settings must be positive");
  if (ba_window < 2 || ba_max_fixed < 0 || ba_iterations < 1)
    return fail("BA window >= 2, iterations >= 1");
  if (!(redundant_fraction > 0 && redundant_fraction <= 1) || redundant_observers < 1)
    return fail("redundancy settings out of range");
  const TriangulationOptions& t = triangulation;
  if (t.neighbours < 0 || !(t.max_hamming > 0) || !(t.ratio > 0 && t.ratio <= 1) ||
      !(t.epipolar_chi2 > 0) || !(t.min_epipole_distance_px >= 0) ||
      !(t.max_cos_parallax > 0 && t.max_cos_parallax < 1) || !(t.scale_factor >= 1))
    return fail("triangulation settings out of range");
  return true;
}

std::optional<LocalMapper> LocalMapper::create(const LocalMapperOptions& options,
                                               const CameraModel& camera,
                                               std::shared_ptr<SharedMap> map, std::string* error) {
  if (!options.is_valid(error)) return std::nullopt;
  if (!map) {
    if (error) *error = "local mapper: no map";
    return std::nullopt;
  }
  return LocalMapper(options, camera, std::move(map));
}

MapperStats LocalMapper::process(std::int64_t kf_id, const KeyframesWaiting& waiting) {
  const std::int64_t t0 = steady_now_ns();
  const std::int64_t c0 = thread_cpu_now_ns();
  MapperStats stats;
  stats.keyframe = kf_id;
  const auto behind = [&] { return waiting && waiting(); };
  {
    const auto lock = map_->lock(MapParty::kMapping);
    if (!map_->map.has_keyframe(kf_id)) return stats;
    stats.points_culled = cull_points(kf_id);
  }
  // ORB-SLAM2 creates new points before it asks whether keyframes wait: the next frames track on
  // them.
  if (options_.triangulate_depthless) stats.points_triangulated = triangulate(kf_id);
  // Point culling runs for every keyframe (it judges points by the keyframe count); the rest works
  // on the neighbourhood, which the next keyframe shares.
  stats.caught_up = behind();
  if (!stats.caught_up) fuse(kf_id, &stats);
  if (options_.bundle_adjustment && !stats.caught_up) bundle_adjust(kf_id, waiting, &stats);
  if (!stats.caught_up && !behind()) {
    const auto lock = map_->lock(MapParty::kMapping);
    stats.keyframes_culled = cull_keyframes(kf_id);
  }
  stats.total_ms = ms_since(t0);
  stats.total_cpu_ms = (thread_cpu_now_ns() - c0) * 1e-6;
  return stats;
}

int LocalMapper::cull_points(std::int64_t kf_id) {
  SlamMap& map = map_->map;
  const std::int64_t serial_now = map.keyframes_created();
  const MapKeyframe* kf = map.keyframe(kf_id);
  // The keyframes of a new segment cannot observe the points of the map before it: culling those
  // for want of observations would erase the older map's newest ground, which relocalisation and
  // the segment's merge need. Its recent points stay as they are.
  if (kf->starts_segment) recent_points_.clear();
  for (std::int64_t pid : kf->point_ids)
    if (pid >= 0)
      if (const MapPoint* p = map.point(pid); p && p->first_keyframe == kf_id)
        recent_points_.push_back(pid);
  int culled = 0;
  std::vector<std::int64_t> keep;
  for (std::int64_t pid : recent_points_) {
    MapPoint* p = map.point(pid);
    if (!p) continue;
    const std::int64_t age = serial_now - p->first_keyframe_serial;
    const bool rarely_found =
        p->visible >= 1 && static_cast<double>(p->found) < options_.min_found_ratio * p->visible;
    int weight = 0;  // observations with depth count 2, without 1 (ORB-SLAM2's stereo rule)
    for (const auto& [o, kp] : p->observations) {
      const MapKeyframe* okf = map.keyframe(o);
      weight += okf && okf->is_depthless(kp) ? 1 : 2;
    }
    if (rarely_found || (age >= options_.cull_after_keyframes &&
                         weight < 2 * options_.min_observing_keyframes - 1)) {
      map.erase_point(pid);
      ++culled;
    } else if (age < options_.cull_after_keyframes + 1) {
      keep.push_back(pid);
    }
  }
  recent_points_ = std::move(keep);
  return culled;
}

int LocalMapper::triangulate(std::int64_t kf_id) {
  TriangulationView view;
  {
    const auto lock = map_->lock(MapParty::kMapping);
    view = triangulation_view(map_->map, kf_id, options_.triangulation);
  }
  // Matching runs on the copy, off the lock: tracking does not wait for it.
  const std::vector<TriangulatedPoint> found =
      triangulate_depthless(view, camera_, options_.triangulation);
  if (found.empty()) return 0;
  const auto lock = map_->lock(MapParty::kMapping);
  SlamMap& map = map_->map;
  int added = 0;
  for (const TriangulatedPoint& t : found) {
    const MapKeyframe* a = map.keyframe(t.kf_a);
    const MapKeyframe* b = map.keyframe(t.kf_b);
    // Tracking may have inserted observations meanwhile; a taken keypoint keeps what it has.
    if (!a || !b || a->point_ids[static_cast<std::size_t>(t.kp_a)] >= 0 ||
        b->point_ids[static_cast<std::size_t>(t.kp_b)] >= 0)
      continue;
    const int row = t.kp_a - static_cast<int>(a->features.size());
    const std::int64_t pid =
        map.add_point(t.p_world_m, a->depthless.features->descriptors.row(row), t.kf_a, t.kp_a);
    map.add_observation(pid, t.kf_b, t.kp_b);
    recent_points_.push_back(pid);
    ++added;
  }
  return added;
}

void LocalMapper::fuse(std::int64_t kf_id, MapperStats* stats) {
  const auto lock = map_->lock(MapParty::kMapping);
  SlamMap& map = map_->map;
  const auto cov = map.covisible(kf_id, 1);
  std::vector<std::int64_t> neighbours;
  for (std::size_t i = 0; i < cov.size() && static_cast<int>(i) < options_.fuse_neighbours; ++i)
    neighbours.push_back(cov[i].first);
  auto own_points = [&]() {
    std::vector<std::int64_t> v;
    if (const MapKeyframe* kf = map.keyframe(kf_id))
      for (std::int64_t pid : kf->point_ids)
        if (pid >= 0) v.push_back(pid);
    return v;
  };
  auto fuse_into = [&](std::int64_t target, const std::vector<std::int64_t>& pids) {
    const FuseCounts c = fuse_into_keyframe(map, camera_, options_.fuse_radius_px, target, pids);
    stats->points_fused += c.merged;
    stats->observations_added += c.attached;
  };
  for (std::int64_t n : neighbours) fuse_into(n, own_points());
  std::vector<std::int64_t> theirs;
  std::unordered_set<std::int64_t> seen;
  for (std::int64_t n : neighbours)
    if (const MapKeyframe* kf = map.keyframe(n))
      for (std::int64_t pid : kf->point_ids)
        if (pid >= 0 && seen.insert(pid).second) theirs.push_back(pid);
  fuse_into(kf_id, theirs);
}

namespace {

/// Ends a solve after the current iteration once `waiting` says so (ORB-SLAM2's abort flag): the
/// parameters keep the last accepted iterate, which is no worse than where the solve started.
class StopWhenKeyframesWait : public ceres::IterationCallback {
 public:
  explicit StopWhenKeyframesWait(const LocalMapper::KeyframesWaiting& waiting)
      : waiting_(waiting) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    if (!waiting_ || !waiting_()) return ceres::SOLVER_CONTINUE;
    stopped_ = true;
    return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
  }
  bool stopped() const { return stopped_; }

 private:
  const LocalMapper::KeyframesWaiting& waiting_;
  bool stopped_ = false;
};

}  // namespace

namespace {

/// A local BA as collected from the map: the window's poses (and the fixed ones anchoring it),
/// the points they see, and every observation of those points from those keyframes.
struct LocalBaProblem {
  struct Obs {
    std::int64_t kf;
    std::int64_t pid;
    Eigen::Vector3d z;
    Eigen::Vector3d sigma;
    bool monocular = false;  ///< a depthless keypoint: (u, v) only
  };
  std::map<std::int64_t, std::array<double, 6>> poses;
  std::set<std::int64_t> fixed;
  std::map<std::int64_t, std::array<double, 3>> points;
  std::vector<Obs> obs;
  /// The window's gravity measurements, with the map's gravity direction (SharedMap).
  std::optional<Eigen::Vector3d> down_world;
  std::map<std::int64_t, GravityObservation> gravity;
};

/// Keyframe `kf_id` and its best covisible neighbours (the window), anchored by up to
/// `ba_max_fixed` keyframes outside it that see its points most. False when the window has
/// fewer than two keyframes. Map locked by the caller.
bool collect_local_ba(const SharedMap& shared, std::int64_t kf_id,
                      const LocalMapperOptions& options, const CameraModel& camera,
                      LocalBaProblem* ba) {
  const SlamMap& map = shared.map;
  const std::int64_t first_kf = map.keyframes().begin()->first;
  std::vector<std::int64_t> window{kf_id};
  for (const auto& [n, shared] : map.covisible(kf_id, options.covisibility_min_shared)) {
    if (static_cast<int>(window.size()) >= options.ba_window) break;
    window.push_back(n);
  }
  if (window.size() < 2) return false;
  for (std::int64_t k : window) ba->poses[k] = to_block(map.keyframe(k)->T_world_cam.inverse());
  std::unordered_map<std::int64_t, int> outside;
  for (std::int64_t k : window)
    for (std::int64_t pid : map.keyframe(k)->point_ids) {
      if (pid < 0 || ba->points.count(pid)) continue;
      const MapPoint* p = map.point(pid);
      if (!p) continue;
      ba->points[pid] = {p->p_world_m.x(), p->p_world_m.y(), p->p_world_m.z()};
      for (const auto& [o, kp] : p->observations)
        if (!ba->poses.count(o)) ++outside[o];
    }
  std::vector<std::pair<int, std::int64_t>> ranked;
  for (const auto& [o, n] : outside) ranked.emplace_back(n, o);
  std::sort(ranked.rbegin(), ranked.rend());
  for (std::size_t i = 0; i < ranked.size() && static_cast<int>(i) < options.ba_max_fixed; ++i) {
    ba->poses[ranked[i].second] = to_block(map.keyframe(ranked[i].second)->T_world_cam.inverse());
    ba->fixed.insert(ranked[i].second);
  }
  // The world is the first keyframe's frame: hold it; with nothing fixed, hold the oldest.
  if (ba->poses.count(first_kf)) ba->fixed.insert(first_kf);
  if (ba->fixed.empty()) ba->fixed.insert(ba->poses.begin()->first);
  ba->down_world = shared.gravity_down_world;
  if (ba->down_world)
    for (std::int64_t k : window)
      if (const auto& g = map.keyframe(k)->gravity; g && !ba->fixed.count(k)) ba->gravity[k] = *g;
  for (const auto& [pid, xyz] : ba->points) {
    const MapPoint* p = map.point(pid);
    for (const auto& [o, kp] : p->observations) {
      if (!ba->poses.count(o)) continue;
      const MapKeyframe* kf = map.keyframe(o);
      const auto k = static_cast<std::size_t>(kp);
      if (kf->is_depthless(kp)) {
        // The disparity row is switched off by an infinite sigma (zero weight, zero Jacobian),
        // which keeps the 3-residual cost Ceres has fixed-size kernels for.
        const std::size_t j = k - kf->features.size();
        const Eigen::Vector2d& px = kf->depthless.pixels[j];
        const double s = kf->depthless.sigma_px[j];
        ba->obs.push_back(LocalBaProblem::Obs{o, pid, Eigen::Vector3d(px.x(), px.y(), 0),
                                              Eigen::Vector3d(s, s, kInfinity), true});
        continue;
      }
      ba->obs.push_back(
          LocalBaProblem::Obs{o, pid, kf->features.measurement(k, camera), kf->features.sigma(k)});
    }
  }
  return true;
}

/// Solves the BA in place (Ceres, RGB-D residual, Huber); stops early when `stop` says so.
/// Each pose enters as two parameter blocks, its rotation (the first three numbers of the block)
/// and its translation (rgbd_reprojection_cost.hpp says why).
bool solve_local_ba(LocalBaProblem* ba, const CameraModel& camera, int iterations,
                    ceres::IterationCallback* stop) {
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  ceres::HuberLoss huber(std::sqrt(kChi2Rgbd95));
  ceres::HuberLoss huber_mono(std::sqrt(kChi2Mono95));
  for (const LocalBaProblem::Obs& o : ba->obs) {
    double* pose = ba->poses[o.kf].data();
    problem.AddResidualBlock(new RgbdReprojectionCost(o.z, o.sigma, camera),
                             o.monocular ? &huber_mono : &huber, pose, pose + 3,
                             ba->points[o.pid].data());
  }
  // No robust loss: a jolt's sample already carries a large sigma (gravity_prior.hpp).
  for (const auto& [k, g] : ba->gravity)
    if (problem.HasParameterBlock(ba->poses[k].data()))
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<GravityCost, 3, 3>(new GravityCost(*ba->down_world, g)),
          nullptr, ba->poses[k].data());
  for (std::int64_t k : ba->fixed)
    if (problem.HasParameterBlock(ba->poses[k].data())) {
      problem.SetParameterBlockConstant(ba->poses[k].data());
      problem.SetParameterBlockConstant(ba->poses[k].data() + 3);
    }
  ceres::Solver::Options so;
  // Dense Schur: the reduced camera system has at most 2 x ba_window free blocks of 3 (60 x 60),
  // too small for a sparse factorisation to pay off. The elimination order is left to Ceres: an
  // explicit ParameterBlockOrdering sorts each group by memory address, which differs from run
  // to run and with it the rounding, and runs must replay bit for bit.
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.max_num_iterations = iterations;
  so.num_threads = 1;  // the other core belongs to tracking
  so.logging_type = ceres::SILENT;
  so.callbacks.push_back(stop);
  ceres::Solver::Summary summary;
  if (ba->obs.empty()) return false;
  ceres::Solve(so, &problem, &summary);
  return summary.IsSolutionUsable();
}

/// Writes the solved poses and points back and drops the observations the solution makes
/// outliers. Map locked by the caller.
void write_back_local_ba(const LocalBaProblem& ba, const CameraModel& camera, SlamMap* map,
                         MapperStats* stats) {
  for (const auto& [k, b] : ba.poses) {
    if (ba.fixed.count(k)) continue;
    MapKeyframe* kf = map->keyframe(k);
    const Eigen::Isometry3d T = from_block(b).inverse();
    if (kf && T.matrix().allFinite()) kf->T_world_cam = T;
  }
  for (const auto& [pid, xyz] : ba.points) {
    MapPoint* p = map->point(pid);
    const Eigen::Vector3d v(xyz[0], xyz[1], xyz[2]);
    if (p && v.allFinite()) p->p_world_m = v;
  }
  for (const LocalBaProblem::Obs& o : ba.obs) {
    const MapPoint* p = map->point(o.pid);
    const MapKeyframe* kf = map->keyframe(o.kf);
    if (!p || !kf) continue;
    auto it = p->observations.find(o.kf);
    if (it == p->observations.end()) continue;
    if (kf->chi2(it->second, p->p_world_m, camera) > kf->chi2_bound(it->second)) {
      map->erase_observation(o.pid, o.kf);
      ++stats->outliers_removed;
    }
  }
}

}  // namespace

void LocalMapper::bundle_adjust(std::int64_t kf_id, const KeyframesWaiting& waiting,
                                MapperStats* stats) {
  const std::int64_t t0 = steady_now_ns();
  LocalBaProblem ba;
  std::uint64_t corrections = 0;
  {
    const auto lock = map_->lock(MapParty::kMapping);
    if (!map_->map.has_keyframe(kf_id)) return;
    corrections = map_->corrections;
    if (!collect_local_ba(*map_, kf_id, options_, camera_, &ba)) return;
  }
  StopWhenKeyframesWait stop(waiting);
  const bool usable = solve_local_ba(&ba, camera_, options_.ba_iterations, &stop);
  stats->ba_interrupted = stop.stopped();
  stats->ba_keyframes = static_cast<int>(ba.poses.size() - ba.fixed.size());
  stats->ba_fixed = static_cast<int>(ba.fixed.size());
  stats->ba_points = static_cast<int>(ba.points.size());
  if (usable) {
    const auto lock = map_->lock(MapParty::kMapping);
    if (map_->corrections != corrections) {
      // Solved on poses from before a loop correction: writing it back would undo the correction
      // in this window (ORB-SLAM2 aborts its local BA for the same reason).
      stats->ba_discarded = true;
    } else {
      write_back_local_ba(ba, camera_, &map_->map, stats);
    }
  }
  stats->ba_ms = ms_since(t0);
}

int LocalMapper::cull_keyframes(std::int64_t kf_id) {
  SlamMap& map = map_->map;
  if (!map.has_keyframe(kf_id)) return 0;
  const std::int64_t first_kf = map.keyframes().begin()->first;
  int culled = 0;
  for (const auto& [n, shared] : map.covisible(kf_id, 1)) {
    if (n == first_kf || n == kf_id || map.in_loop_edge(n)) continue;
    const MapKeyframe* kf = map.keyframe(n);
    if (!kf) continue;
    int points = 0, redundant = 0;
    for (std::size_t k = 0; k < kf->features.size(); ++k) {  // keypoints with depth
      const MapPoint* p = kf->point_ids[k] >= 0 ? map.point(kf->point_ids[k]) : nullptr;
      if (!p || kf->features.depth_m[k] > options_.near_depth_m) continue;
      ++points;
      if (static_cast<int>(p->observations.size()) - 1 >= options_.redundant_observers) ++redundant;
    }
    if (points == 0 || redundant < options_.redundant_fraction * points) continue;
    const auto cov = map.covisible(n, 1);
    std::int64_t parent = -1;
    for (const auto& [c, s] : cov)
      if (c != n) {
        parent = c;
        break;
      }
    if (parent < 0) continue;
    map.cull_keyframe(n, parent);
    ++culled;
  }
  return culled;
}

}  // namespace rgbdquad::slam
