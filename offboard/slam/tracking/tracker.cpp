// Tracking against the local map; see tracker.hpp.
#include "slam/tracking/tracker.hpp"

#include <algorithm>
#include <numeric>
#include <unordered_map>
#include <unordered_set>

#include "slam/map/place_index.hpp"
#include "slam/tracking/registration.hpp"
#include "slam/tracking/rolling_shutter.hpp"

namespace rgbdquad::slam {

namespace {

/// The motion T scaled to a fraction s of itself (rotation angle and translation scaled).
Eigen::Isometry3d scale_motion(const Eigen::Isometry3d& T, double s) {
  const Eigen::AngleAxisd aa(T.rotation());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(aa.angle() * s, aa.axis()).toRotationMatrix();
  out.translation() = T.translation() * s;
  return out;
}

constexpr double kDegPerRad = 57.29577951308232;

/// ORB-SLAM2's nMinObs for the reference keyframe's tracked points: 3 observations, or 2 while the
/// map has <= 2 keyframes; an RGB-D observation counts 2 there, i.e. 2 keyframes, or 1.
int keyframe_min_observations(const SlamMap& map) { return map.keyframes().size() > 2 ? 2 : 1; }

}  // namespace

CameraShift camera_shift(const Eigen::Isometry3d& T_cam_world_a,
                         const Eigen::Isometry3d& T_cam_world_b) {
  // T_a_b = T_a_world * T_world_b: camera b in camera a's frame.
  const Eigen::Isometry3d T_a_b = T_cam_world_a * T_cam_world_b.inverse();
  return {T_a_b.translation().norm(), rotation_angle_rad(T_a_b) * kDegPerRad};
}

ProjectionFitOptions projection_fit_options(const TrackerOptions& o) {
  ProjectionFitOptions f;
  f.search = o.search;
  f.refine_radius_px = o.refine_radius_px;
  f.wide_radius_factor = o.wide_radius_factor;
  f.min_matches_first_pass = o.min_matches_first_pass;
  f.pose = o.pose;
  return f;
}

const char* to_string(KeyframeReason r) {
  switch (r) {
    case KeyframeReason::kNone:
      return "none";
    case KeyframeReason::kFirst:
      return "first";
    case KeyframeReason::kViewChanged:
      return "view_changed";
    case KeyframeReason::kNeedNear:
      return "need_near";
    case KeyframeReason::kBoth:
      return "view_changed+need_near";
    case KeyframeReason::kRedundant:
      return "redundant";
    case KeyframeReason::kMapperBusy:
      return "mapper_busy";
  }
  return "?";
}

bool TrackerOptions::is_valid(std::string* error) const {
  auto fail = [&](const char* m) {
    if (error) *error = std::string("tracker: ") + m;
    return false;
  };
  if (!(search.radius_px > 0) || !(refine_radius_px > 0) || !(wide_radius_factor >= 1))
    return fail("search radii must be positive");
  if (!(search.ratio > 0 && search.ratio <= 1)) return fail("ratio must be in (0, 1]");
  if (min_inliers_tracking < 6 || min_inliers_relocalised < min_inliers_tracking)
    return fail("min_inliers_tracking must be >= 6 and <= min_inliers_relocalised");
  if (max_local_keyframes < 1 || covisible_per_keyframe < 0)
    return fail("local map sizes must be positive");
  if (!(keyframe_tracked_ratio > 0 && keyframe_tracked_ratio < 1))
    return fail("keyframe_tracked_ratio must be in (0, 1)");
  if (!(keyframe_busy_tracked_ratio >= 0 && keyframe_busy_tracked_ratio <= keyframe_tracked_ratio))
    return fail("keyframe_busy_tracked_ratio must be in [0, keyframe_tracked_ratio]");
  if (!(near_depth_m > 0)) return fail("near_depth_m must be positive");
  if (pose.rounds < 1 || pose.iterations_per_round < 1)
    return fail("pose optimiser needs >= 1 round and iteration");
  if (!(max_velocity_scale >= 1)) return fail("max_velocity_scale must be >= 1");
  if (!(cross_check_tracked_ratio >= 0 && cross_check_tracked_ratio < 1))
    return fail("cross_check_tracked_ratio must be in [0, 1)");
  if (!(cross_check_same_pose_m >= 0) || !(cross_check_same_pose_deg >= 0))
    return fail("cross_check_same_pose_m and cross_check_same_pose_deg must be >= 0");
  if (!(max_predicted_gap_s > 0)) return fail("max_predicted_gap_s must be positive");
  if (!(max_acceleration_m_per_s2 > 0) || !(motion_bound_baseline_s > 0))
    return fail("max_acceleration_m_per_s2 and motion_bound_baseline_s must be positive");
  if (!(max_speed_m_per_s > 0) || !(max_rate_rad_per_s > 0) || !(motion_margin_m >= 0) ||
      !(motion_margin_rad >= 0))
    return fail("motion bounds must be positive");
  if (min_segment_features < min_inliers_tracking)
    return fail("min_segment_features must be >= min_inliers_tracking");
  if (!(segment_merge_period_s >= 0)) return fail("segment_merge_period_s must be >= 0");
  if (!(max_attitude_disagreement_deg >= 0))
    return fail("max_attitude_disagreement_deg must be >= 0 (0: off)");
  if (!gravity.is_valid(error)) return false;
  if (depthless_map_points && !depthless_observations)
    return fail("depthless_map_points needs depthless_observations");
  if (!(rolling_shutter_readout_s >= 0 && rolling_shutter_readout_s < 0.1))
    return fail("rolling_shutter_readout_s must be in [0, 0.1) s");
  if (!(rolling_shutter_angular_accel_rad_per_s2 > 0))
    return fail("rolling_shutter_angular_accel_rad_per_s2 must be > 0");
  return matching.is_valid(error) && ransac.is_valid(error);
}

std::optional<Tracker> Tracker::create(const TrackerOptions& options, const CameraModel& camera,
                                       std::shared_ptr<SharedMap> map, std::string* error) {
  if (!options.is_valid(error)) return std::nullopt;
  if (!map) {
    if (error) *error = "tracker: no map";
    return std::nullopt;
  }
  return Tracker(options, camera, std::move(map));
}

std::unique_lock<MapMutex> Tracker::lock_map() const {
  const std::int64_t t0 = steady_now_ns();
  std::unique_lock<MapMutex> lock = map_->lock(MapParty::kTracking);
  lock_wait_ms_ += ms_since(t0);
  return lock;
}

Tracker::LocalMap Tracker::build_local_map(const std::vector<std::int64_t>& seed_points,
                                           std::int64_t fallback_kf) const {
  LocalMap local;
  const SlamMap& map = map_->map;
  // Keyframes that see the seed points, by how many they see.
  std::unordered_map<std::int64_t, int> votes;
  for (std::int64_t pid : seed_points)
    if (const MapPoint* p = map.point(pid))
      for (const auto& [kf, kp] : p->observations) ++votes[kf];
  std::vector<std::pair<int, std::int64_t>> ranked;
  for (const auto& [kf, n] : votes) ranked.emplace_back(n, kf);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second > b.second;
  });
  std::unordered_set<std::int64_t> chosen;
  const auto cap = static_cast<std::size_t>(options_.max_local_keyframes);
  auto take = [&](std::int64_t kf) {
    if (local.keyframes.size() >= cap || !map.has_keyframe(kf) || !chosen.insert(kf).second) return;
    local.keyframes.push_back(kf);
  };
  if (ranked.empty() && fallback_kf >= 0) take(fallback_kf);
  for (const auto& [n, kf] : ranked) take(kf);
  // Neighbours of the best few, while there is room (covisibility is computed on demand, so the
  // expansion is limited to the kMaxExpanded best keyframes to bound the per-frame cost).
  constexpr std::size_t kMaxExpanded = 3;
  const std::vector<std::int64_t> firsts(
      local.keyframes.begin(),
      local.keyframes.begin() + std::min(kMaxExpanded, local.keyframes.size()));
  for (std::int64_t kf : firsts) {
    if (local.keyframes.size() >= cap) break;
    const auto cov = map.covisible(kf, 1);
    for (std::size_t i = 0; i < cov.size() && static_cast<int>(i) < options_.covisible_per_keyframe;
         ++i)
      take(cov[i].first);
  }
  std::unordered_set<std::int64_t> seen;
  for (std::int64_t kf_id : local.keyframes) {
    const MapKeyframe* kf = map.keyframe(kf_id);
    for (std::int64_t pid : kf->point_ids) {
      if (pid < 0 || !seen.insert(pid).second) continue;
      const MapPoint* p = map.point(pid);
      if (p) local.points.push_back(LocalPoint{pid, p->p_world_m, p->descriptor});
    }
  }
  return local;
}

bool Tracker::cross_check_needed(const Fit& fit) const {
  if (!fit.ok || !(options_.cross_check_tracked_ratio > 0)) return false;
  if (static_cast<int>(fit.inliers) < options_.min_inliers_relocalised) return true;
  const auto lock = lock_map();
  const int ref_tracked = map_->map.tracked_points(reference_kf_, min_observations());
  return static_cast<double>(fit.inliers) < options_.cross_check_tracked_ratio * ref_tracked;
}

Tracker::Fit Tracker::fit_local_map(const LocalMap& local, const FrameInput& in,
                                    const Eigen::Isometry3d& T_guess,
                                    double first_radius_px) const {
  return fit_by_projection(local.points, in.tf, camera_, T_guess, first_radius_px,
                           frame_fit_options(), in.depthless.size() ? &in.depthless : nullptr);
}

ProjectionFitOptions Tracker::frame_fit_options() const {
  ProjectionFitOptions fo = projection_fit_options(options_);
  if (frame_gravity_)
    if (const auto down_world = gravity_reference_.down_world())
      fo.pose.gravity =
          GravityPrior{*down_world, frame_gravity_->down_cam, frame_gravity_->sigma_rad};
  return fo;
}

std::optional<Tracker::KeyframeGuess> Tracker::pose_from_keyframes(
    const TrackedFeatures& frame, const std::vector<std::int64_t>& candidates,
    std::uint64_t seed) const {
  std::optional<KeyframeGuess> best;
  std::size_t best_inliers = 0;
  for (std::int64_t kf_id : candidates) {
    KeyframePoints kp;
    {
      const auto lock = lock_map();
      kp = keyframe_points(map_->map, kf_id);
    }
    if (kp.keyframe < 0) continue;
    const auto reg = register_to_keyframe(*frame.features, kp, options_.matching, options_.ransac,
                                          seed ^ static_cast<std::uint64_t>(kf_id),
                                          options_.min_relocalisation_ransac_inliers);
    if (reg && reg->inliers > best_inliers) {
      best_inliers = reg->inliers;
      best = KeyframeGuess{reg->T_world_cam, kf_id};
    }
  }
  return best;
}

std::int64_t Tracker::insert_keyframe(const RgbdFrame& frame, const TrackedFeatures& tf,
                                      const TrackedFeatures& depthless, const cv::Mat& thumbnail,
                                      const Eigen::Isometry3d& T_world_cam, const LocalMap& local,
                                      const std::vector<int>& point_of_keypoint,
                                      const std::vector<int>& point_of_depthless) {
  MapKeyframe kf;
  const auto lock = lock_map();
  SlamMap& map = map_->map;
  // Keyframe ids follow the frame index, but never reuse an id of a loaded (or culled) keyframe.
  std::int64_t id = frame.index;
  if (!map.keyframes().empty()) id = std::max(id, map.keyframes().rbegin()->first + 1);
  if (!map.culled().empty()) id = std::max(id, map.culled().rbegin()->first + 1);
  kf.id = id;
  kf.stamp_s = frame.stamp_s;
  kf.T_world_cam = T_world_cam;
  kf.features = tf;
  if (options_.depthless_map_points) kf.depthless = depthless;
  kf.thumbnail = thumbnail;
  kf.gravity = frame_gravity_;
  // Near features without a map point become points, nearest first; at least min_new_points.
  std::vector<int> fresh;
  for (std::size_t k = 0; k < tf.size(); ++k)
    if (point_of_keypoint.empty() || point_of_keypoint[k] < 0) fresh.push_back(static_cast<int>(k));
  std::stable_sort(fresh.begin(), fresh.end(), [&](int a, int b) {
    return tf.depth_m[static_cast<std::size_t>(a)] < tf.depth_m[static_cast<std::size_t>(b)];
  });
  map.add_keyframe(std::move(kf));
  if (segment_keyframes_) ++*segment_keyframes_;
  if (frame_gravity_) {
    gravity_reference_.add(T_world_cam.linear(), *frame_gravity_);
    map_->gravity_down_world = gravity_reference_.down_world();
  }
  for (std::size_t k = 0; k < point_of_keypoint.size(); ++k) {
    if (point_of_keypoint[k] < 0) continue;
    const std::int64_t pid = local.points[static_cast<std::size_t>(point_of_keypoint[k])].id;
    if (map.has_point(pid)) map.add_observation(pid, id, static_cast<int>(k));
  }
  if (options_.depthless_map_points)
    for (std::size_t k = 0; k < point_of_depthless.size() && k < depthless.size(); ++k) {
      if (point_of_depthless[k] < 0) continue;
      const std::int64_t pid = local.points[static_cast<std::size_t>(point_of_depthless[k])].id;
      if (map.has_point(pid)) map.add_observation(pid, id, static_cast<int>(tf.size() + k));
    }
  int created = 0;
  for (int k : fresh) {
    const auto ks = static_cast<std::size_t>(k);
    if (tf.depth_m[ks] > options_.near_depth_m && created >= options_.min_new_points) break;
    map.add_point(T_world_cam * tf.features->points_cam_m[ks], tf.features->descriptors.row(k), id,
                  k);
    ++created;
  }
  reference_kf_ = id;
  return id;
}

int Tracker::min_observations() const {
  // A young map segment (TrackerOptions::restart_when_lost) has keyframes of its own only.
  if (segment_keyframes_ && *segment_keyframes_ <= 2) return 1;
  return keyframe_min_observations(map_->map);
}

std::optional<Eigen::Vector3d> Tracker::predicted_rotation_rate_rad_per_s() const {
  if (state_ != TrackingState::kTracking || !have_velocity_ || !(last_interval_s_ > 0))
    return std::nullopt;
  const Eigen::AngleAxisd aa(T_last_cur_velocity_.rotation());
  return Eigen::Vector3d(aa.axis() * (aa.angle() / last_interval_s_));
}

TrackResult Tracker::track(const RgbdFrame& frame, std::shared_ptr<const FrameFeatures> features,
                           const FeatureOptions& feature_options, KeyframeAdmission admission) {
  lock_wait_ms_ = 0;
  frame_gravity_.reset();
  if (options_.gravity.enabled) frame_gravity_ = observe_gravity(frame, options_.gravity);
  FrameInput in{frame,
                TrackedFeatures{},
                make_thumbnail(frame.rgb),
                options_.ransac.max_iterations * 0x9E3779B97F4A7C15ull ^
                    static_cast<std::uint64_t>(frame.index),
                nullptr,
                &feature_options,
                TrackedFeatures{}};
  if (options_.depthless_observations && features->depthless) {
    const auto omega = options_.rolling_shutter_readout_s > 0 ? predicted_rotation_rate_rad_per_s()
                                                              : std::optional<Eigen::Vector3d>{};
    in.depthless = omega ? unrolled(*features->depthless, in, *omega)
                         : TrackedFeatures::from(features->depthless, camera_, feature_options);
  }
  if (options_.rolling_shutter_readout_s > 0) {
    in.extracted = features;
    const auto omega = predicted_rotation_rate_rad_per_s();
    in.tf =
        omega ? unrolled(in, *omega) : TrackedFeatures::from(features, camera_, feature_options);
  } else {
    in.tf = TrackedFeatures::from(std::move(features), camera_, feature_options);
  }
  TrackResult out = track_steps(in, admission);
  out.map_lock_wait_ms = lock_wait_ms_;
  out.gravity_prior = frame_gravity_ && gravity_reference_.down_world().has_value();
  return out;
}

TrackedFeatures Tracker::unrolled(const FrameInput& in,
                                  const Eigen::Vector3d& omega_cam_rad_per_s) const {
  return unrolled(*in.extracted, in, omega_cam_rad_per_s);
}

TrackedFeatures Tracker::unrolled(const FrameFeatures& extracted, const FrameInput& in,
                                  const Eigen::Vector3d& omega_cam_rad_per_s) const {
  FrameFeatures f = extracted;
  unroll_rotation(&f, omega_cam_rad_per_s, options_.rolling_shutter_readout_s, in.frame.rgb.rows);
  return TrackedFeatures::from(std::make_shared<const FrameFeatures>(std::move(f)), camera_,
                               *in.feature_options);
}

void Tracker::refit_rolling_shutter(FrameInput* in, Attempt* a, TrackResult* out) const {
  if (!in->extracted) return;
  const double dt = in->frame.stamp_s - last_stamp_s_;
  // The rate's prior: the motion model's, else the fit's own turn since the last tracked frame;
  // with neither (the first fit after a loss), zero within the fastest turn tracking accepts.
  // The prior is a mean rate over an interval: its age at this frame is from the interval's middle.
  std::optional<Eigen::Vector3d> prior = predicted_rotation_rate_rad_per_s();
  double prior_age_s = dt + 0.5 * last_interval_s_;
  if (!prior && state_ == TrackingState::kTracking && dt > 0 &&
      dt <= options_.max_predicted_gap_s) {
    const Eigen::AngleAxisd step(T_world_last_.linear().transpose() *
                                 a->fit.T_cam_world.linear().transpose());
    prior = Eigen::Vector3d(step.axis() * (step.angle() / dt));
    prior_age_s = 0.5 * dt;
  }
  const TrackedFeatures raw = TrackedFeatures::from(in->extracted, camera_, *in->feature_options);
  const int rows = in->frame.rgb.rows;
  const double row_s = options_.rolling_shutter_readout_s / rows;
  const double mid_row = 0.5 * (rows - 1);
  ProjectionFitOptions fo = frame_fit_options();
  RollingShutterModel rs;
  rs.omega_prior_rad_per_s = prior.value_or(Eigen::Vector3d::Zero());
  rs.omega_sigma_rad_per_s = prior ? options_.rolling_shutter_angular_accel_rad_per_s2 * prior_age_s
                                   : options_.max_rate_rad_per_s;
  std::vector<PoseObservation> obs;
  std::vector<std::size_t> kp_of_obs;
  for (std::size_t k = 0; k < a->fit.point_of_keypoint.size(); ++k) {
    const int p = a->fit.point_of_keypoint[k];
    if (p < 0) continue;
    obs.push_back(PoseObservation{a->local.points[static_cast<std::size_t>(p)].p_world_m,
                                  raw.measurement(k, camera_), raw.sigma(k)});
    rs.row_time_s.push_back((in->extracted->keypoints[k].pt.y - mid_row) * row_s);
    kp_of_obs.push_back(k);
  }
  const std::size_t n_rgbd = obs.size();
  if (in->depthless.size() && !a->fit.point_of_depthless.empty()) {
    // The depthless matches as extracted (in->depthless was rotated by the predicted rate).
    const TrackedFeatures raw_depthless =
        TrackedFeatures::from(in->extracted->depthless, camera_, *in->feature_options);
    for (std::size_t k = 0; k < a->fit.point_of_depthless.size(); ++k) {
      const int p = a->fit.point_of_depthless[k];
      if (p < 0) continue;
      obs.push_back(pose_observation(a->local.points[static_cast<std::size_t>(p)].p_world_m,
                                     raw_depthless, k, camera_, true));
      rs.row_time_s.push_back((in->extracted->depthless->keypoints[k].pt.y - mid_row) * row_s);
      kp_of_obs.push_back(k);
    }
  }
  fo.pose.rolling_shutter = std::move(rs);
  const PoseOptimizerResult r = optimize_pose(a->fit.T_cam_world, obs, camera_, fo.pose);
  int rgbd_inliers = 0;
  for (std::size_t i = 0; i < n_rgbd; ++i) rgbd_inliers += r.inlier[i] ? 1 : 0;
  if (!r.ok || rgbd_inliers < a->needed) return;
  a->fit.T_cam_world = r.T_cam_world;
  a->fit.depthless_inliers = 0;
  for (std::size_t i = 0; i < obs.size(); ++i) {
    std::vector<int>& matches = i < n_rgbd ? a->fit.point_of_keypoint : a->fit.point_of_depthless;
    if (!r.inlier[i]) matches[kp_of_obs[i]] = -1;
    if (r.inlier[i] && i >= n_rgbd) ++a->fit.depthless_inliers;
  }
  a->fit.inliers = static_cast<std::size_t>(rgbd_inliers);
  out->rolling_shutter_rate_rad_per_s = r.omega_cam_rad_per_s;
  // The frame as a global shutter at the middle row would have seen it: what a keyframe keeps.
  in->tf = unrolled(*in, r.omega_cam_rad_per_s);
}

TrackResult Tracker::track_steps(FrameInput& in, KeyframeAdmission admission) {
  bool map_empty;
  {
    const auto lock = lock_map();
    map_empty = map_->map.keyframes().empty();
  }
  if (map_empty) return initialise(in);
  TrackResult out;
  follow_map_corrections(&out);
  const Eigen::Isometry3d T_world_pred = predict(in.frame, &out);
  Attempt attempt = search_local_map(in, T_world_pred, &out);
  recover_or_cross_check(in, &attempt, &out);
  out.matches = attempt.fit.matches;
  out.inliers = attempt.fit.inliers;
  Verdict verdict = judge(in.frame, attempt, &out);
  // Only where the prediction still vouches for the pose: after a longer gap the bound is final,
  // as that is where its wrong fits came from (a 0.32 m fit after 260 ms in a demo-loop run).
  if (verdict == Verdict::kOffPath && options_.confirm_off_path && !out.prediction_stale &&
      confirm_off_path(in, &attempt, &out))
    verdict = Verdict::kAccepted;
  if (verdict != Verdict::kAccepted) {
    out.attitude_refused = verdict == Verdict::kAttitudeDisagrees;
    if (const auto start = restart_pose(in, admission.segment_start_allowed))
      return start_segment(in, *start, std::move(out));
    return declare_lost(&out);
  }
  if (options_.rolling_shutter_readout_s > 0) refit_rolling_shutter(&in, &attempt, &out);
  out.depthless_inliers = attempt.fit.depthless_inliers;
  const Eigen::Isometry3d T_world_cam = attempt.fit.T_cam_world.inverse();
  std::vector<std::int64_t> matched =
      decide_keyframe(in, attempt, T_world_cam, admission.allowed, admission.mapper_idle, &out);
  // A cross-check that replaced a relocalised fit continues from a tracked frame.
  advance(in.frame, T_world_cam, std::move(matched), !out.relocalised || out.cross_checked, &out);
  if (segment_first_kf_ && options_.segment_merge_period_s > 0 &&
      in.frame.stamp_s - last_merge_try_s_ >= options_.segment_merge_period_s)
    merge_segment(in, &out);
  const auto lock = lock_map();
  out.map_keyframes = map_->map.keyframes().size();
  out.map_points = map_->map.points().size();
  return out;
}

TrackResult Tracker::initialise(const FrameInput& in) {
  TrackResult out;
  out.state = TrackingState::kInitialising;
  if (static_cast<int>(in.tf.size()) < options_.min_init_features) return out;
  const Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  last_q_nav_cam_ = in.frame.q_nav_cam;
  out.keyframe_id =
      insert_keyframe(in.frame, in.tf, in.depthless, in.thumbnail, T_world_cam, LocalMap{}, {}, {});
  state_ = TrackingState::kTracking;
  T_world_last_ = T_world_cam;
  last_pose_known_ = true;
  last_stamp_s_ = in.frame.stamp_s;
  have_velocity_ = false;
  motion_bound_.reset();
  motion_bound_.add(in.frame.stamp_s, T_world_cam.translation());
  last_points_.clear();
  out.state = TrackingState::kTracking;
  out.T_world_cam = T_world_cam;
  out.reference_keyframe = out.keyframe_id;
  out.keyframe = true;
  out.keyframe_wanted = KeyframeReason::kFirst;
  T_ref_last_ = Eigen::Isometry3d::Identity();
  return out;
}

std::optional<Tracker::RestartPose> Tracker::restart_pose(const FrameInput& in,
                                                          bool segment_start_allowed) const {
  const double gap_s = in.frame.stamp_s - last_stamp_s_;
  if (!options_.restart_when_lost || !segment_start_allowed || !last_pose_known_ || !(gap_s > 0) ||
      static_cast<int>(in.tf.size()) < options_.min_segment_features)
    return std::nullopt;
  // Within max_predicted_gap_s of the last tracked frame the motion model vouches for the pose;
  // after a longer gap the pose is a guess (restart_after_gap), its rotation from the attitude
  // when the frames carry one. Either way the last velocity is extrapolated over the gap, at most
  // max_velocity_scale intervals, as predict() does.
  const bool after_gap = gap_s > options_.max_predicted_gap_s;
  if (after_gap ? !options_.restart_after_gap : !restart_motion_known_) return std::nullopt;
  Eigen::Isometry3d T_world_guess = T_world_last_;
  if (restart_motion_known_) {
    const double s = std::clamp(gap_s / last_interval_s_, 0.0, options_.max_velocity_scale);
    T_world_guess = T_world_last_ * scale_motion(T_last_cur_velocity_, s);
  }
  if (after_gap) T_world_guess.linear() = attitude_rotation(in.frame);
  return RestartPose{T_world_guess, after_gap};
}

Eigen::Matrix3d Tracker::attitude_rotation(const RgbdFrame& frame) const {
  if (!frame.q_nav_cam || !last_q_nav_cam_) return T_world_last_.linear();
  const Eigen::Quaterniond q_last_cur =
      last_q_nav_cam_->normalized().conjugate() * frame.q_nav_cam->normalized();
  return T_world_last_.linear() * q_last_cur.toRotationMatrix();
}

bool Tracker::disagrees_with_attitude(const RgbdFrame& frame,
                                      const Eigen::Isometry3d& T_world_cam) const {
  if (!(options_.max_attitude_disagreement_deg > 0) || !frame.q_nav_cam || !last_q_nav_cam_)
    return false;
  const Eigen::AngleAxisd d(attitude_rotation(frame).transpose() * T_world_cam.linear());
  return std::abs(d.angle()) * 180.0 / M_PI > options_.max_attitude_disagreement_deg;
}

TrackResult Tracker::start_segment(const FrameInput& in, const RestartPose& start,
                                   TrackResult out) {
  const Eigen::Isometry3d& T_world_guess = start.T_world_cam;
  // Neither the prediction nor the keyframe database gave a pose: the frame starts a new map
  // segment of its own points at the predicted pose, in the same map and world frame, so that
  // tracking goes on at once. Loop closing joins the segment to the keyframes it does not share
  // points with when it recognises their place.
  segment_keyframes_ = 0;
  out.keyframe_id = insert_keyframe(in.frame, in.tf, in.depthless, in.thumbnail, T_world_guess,
                                    LocalMap{}, {}, {});
  // A segment started inside a segment not yet merged extends it: both move as one when merged.
  if (!segment_first_kf_) segment_first_kf_ = out.keyframe_id;
  last_merge_try_s_ = in.frame.stamp_s;
  {
    const auto lock = lock_map();
    if (MapKeyframe* kf = map_->map.keyframe(out.keyframe_id)) kf->starts_segment = true;
  }
  out.keyframe = true;
  out.new_segment = true;
  out.keyframe_wanted = KeyframeReason::kFirst;
  out.reference_keyframe = out.keyframe_id;
  out.T_kf_cam = Eigen::Isometry3d::Identity();
  motion_bound_.reset();
  if (start.after_gap) {
    // A guessed pose: no velocity from it, and the jump from what a consumer estimated meanwhile
    // is the world frame moving under it, declared like a loop correction.
    state_ = TrackingState::kLost;
    const auto lock = lock_map();
    corrections_seen_ = ++map_->corrections;
    out.map_corrections = corrections_seen_;
  }
  // The motion model carries on: the camera did not stop because the fit failed, and the segment
  // starts at the motion model's pose even when the failed attempt had relocalised (that pose
  // was refused; the velocity before it still holds).
  advance(in.frame, T_world_guess, {}, true, &out);
  const auto lock = lock_map();
  out.map_keyframes = map_->map.keyframes().size();
  out.map_points = map_->map.points().size();
  return out;
}

void Tracker::merge_segment(const FrameInput& in, TrackResult* out) {
  last_merge_try_s_ = in.frame.stamp_s;
  const std::int64_t first = *segment_first_kf_;
  std::vector<std::int64_t> candidates;
  {
    const auto lock = lock_map();
    candidates = rank_keyframes_by_appearance(map_->map, in.thumbnail,
                                              options_.relocalisation_candidates, first);
  }
  if (candidates.empty()) return;
  const std::int64_t t0 = steady_now_ns();
  const auto found = fit_from_keyframes(in, candidates);
  out->relocalise_ms += ms_since(t0);
  if (!found || !found->fit.ok ||
      static_cast<int>(found->fit.inliers) < options_.min_inliers_relocalised ||
      !found->fit.T_cam_world.matrix().allFinite())
    return;
  if (disagrees_with_attitude(in.frame, found->fit.T_cam_world.inverse())) {
    out->attitude_refused = true;
    return;
  }
  // The same camera in both maps: the correction takes the segment's world onto the older map's.
  const Eigen::Isometry3d T_old_seg = found->fit.T_cam_world.inverse() * out->T_world_cam.inverse();
  {
    const auto lock = lock_map();
    SlamMap& map = map_->map;
    for (auto& [id, kf] : map.keyframes())
      if (id >= first) map.keyframe(id)->T_world_cam = T_old_seg * kf.T_world_cam;
    std::vector<std::int64_t> moved;
    for (const auto& [pid, p] : map.points())
      if (p.first_keyframe >= first) moved.push_back(pid);
    for (std::int64_t pid : moved) {
      MapPoint* p = map.point(pid);
      p->p_world_m = T_old_seg * p->p_world_m;
    }
    corrections_seen_ = ++map_->corrections;
  }
  T_world_last_ = T_old_seg * T_world_last_;
  out->T_world_cam = T_world_last_;
  out->map_corrections = corrections_seen_;
  out->segment_merged = true;
  // Positions before the merge are in the segment's world: the bound starts again from here.
  motion_bound_.reset();
  motion_bound_.add(in.frame.stamp_s, T_world_last_.translation());
  segment_first_kf_.reset();
}

void Tracker::follow_map_corrections(TrackResult* out) {
  // A loop correction moved the map since the last frame: carry the last pose along with its
  // reference keyframe so that the prediction lands in the corrected map.
  const auto lock = lock_map();
  if (map_->corrections != corrections_seen_) {
    corrections_seen_ = map_->corrections;
    motion_bound_.reset();  // its positions are in the world frame before the correction
    if (auto T_kf = map_->map.resolve_pose(reference_kf_)) T_world_last_ = *T_kf * T_ref_last_;
  }
  out->map_corrections = corrections_seen_;
}

Eigen::Isometry3d Tracker::predict(const RgbdFrame& frame, TrackResult* out) const {
  Eigen::Isometry3d T_world_pred = T_world_last_;
  if (state_ == TrackingState::kTracking && have_velocity_ && last_interval_s_ > 0) {
    const double s = std::clamp((frame.stamp_s - last_stamp_s_) / last_interval_s_, 0.0,
                                options_.max_velocity_scale);
    T_world_pred = T_world_last_ * scale_motion(T_last_cur_velocity_, s);
  }
  if (options_.attitude_prior && state_ == TrackingState::kTracking && frame.q_nav_cam &&
      last_q_nav_cam_) {
    T_world_pred.linear() = attitude_rotation(frame);
    out->attitude_predicted = true;
  }
  return T_world_pred;
}

Tracker::Attempt Tracker::search_local_map(const FrameInput& in,
                                           const Eigen::Isometry3d& T_world_pred,
                                           TrackResult* out) {
  Attempt a;
  std::int64_t t0 = steady_now_ns();
  {
    const auto lock = lock_map();
    if (!map_->map.has_keyframe(reference_kf_) && !map_->map.keyframes().empty())
      reference_kf_ = map_->map.keyframes().rbegin()->first;
    a.local = build_local_map(last_points_, reference_kf_);
  }
  out->local_map_ms = ms_since(t0);
  out->local_points = a.local.points.size();
  t0 = steady_now_ns();
  if (state_ == TrackingState::kTracking)
    a.fit = fit_local_map(a.local, in, T_world_pred.inverse(), options_.search.radius_px);
  out->search_ms = ms_since(t0);
  // After a gap the prediction cannot vouch for, a projection fit is held to the relocalisation
  // bar: the pose is as unconstrained as a keyframe-database guess.
  out->prediction_stale = state_ == TrackingState::kTracking &&
                          in.frame.stamp_s - last_stamp_s_ > options_.max_predicted_gap_s;
  a.needed =
      out->prediction_stale ? options_.min_inliers_relocalised : options_.min_inliers_tracking;
  return a;
}

void Tracker::recover_or_cross_check(const FrameInput& in, Attempt* a, TrackResult* out) {
  // Recovery from the keyframe database: lost, the prediction found too little, or the gap was
  // longer than the prediction vouches for. In that last case a projection fit from the stale pose
  // can lock onto repeated texture at the wrong offset and still pass the relocalisation bar (HIL
  // scenario 4 after a 1.7 s link stall: 65 inliers 0.21 m off, then a keyframe made there), so
  // the database is asked as well and the fit with more inliers is kept.
  // A weak fit (cross_check_needed) gets the same second opinion from the reference keyframe alone.
  const bool recover =
      !a->fit.ok || static_cast<int>(a->fit.inliers) < a->needed || out->prediction_stale;
  out->cross_checked = !recover && cross_check_needed(a->fit);
  if (!recover && !out->cross_checked) return;
  const std::int64_t t0 = steady_now_ns();
  std::vector<std::int64_t> candidates;
  if (out->cross_checked) {
    candidates.push_back(reference_kf_);
  } else {
    const auto lock = lock_map();
    candidates =
        rank_keyframes_by_appearance(map_->map, in.thumbnail, options_.relocalisation_candidates);
    if (state_ == TrackingState::kTracking && map_->map.has_keyframe(reference_kf_) &&
        std::find(candidates.begin(), candidates.end(), reference_kf_) == candidates.end())
      candidates.insert(candidates.begin(), reference_kf_);
  }
  if (auto from_keyframes = fit_from_keyframes(in, candidates)) {
    LocalMap& around = from_keyframes->local;
    Fit& refit = from_keyframes->fit;
    // A cross-check that lands on the same pose changes nothing: the projection fit, matched
    // against the local map of the last frame's points, stays (and with it the keyframe's links
    // to the map). Only a different pose with more inliers replaces it.
    bool replaces = true;
    if (out->cross_checked && refit.ok) {
      const CameraShift d = camera_shift(a->fit.T_cam_world, refit.T_cam_world);
      out->cross_check_shift_m = d.metres;
      out->cross_check_shift_deg = d.degrees;
      replaces = out->cross_check_shift_m > options_.cross_check_same_pose_m ||
                 out->cross_check_shift_deg > options_.cross_check_same_pose_deg;
    }
    if (refit.ok && refit.inliers > a->fit.inliers && replaces) {
      a->fit = std::move(refit);
      a->local = std::move(around);
      out->local_points = a->local.points.size();
      out->relocalised = true;
      // A pose from the keyframe database, not from the motion prior, must meet the
      // relocalisation bar whether or not tracking was lost just before: in a room of repeated
      // texture a wrong place can reach the tracking bar (seen in a HIL flight: a 1.5 m jump).
      a->needed = options_.min_inliers_relocalised;
    }
  }
  out->relocalise_ms = ms_since(t0);
}

std::optional<Tracker::Attempt> Tracker::fit_from_keyframes(
    const FrameInput& in, const std::vector<std::int64_t>& candidates) const {
  const auto guess = pose_from_keyframes(in.tf, candidates, in.seed);
  if (!guess) return std::nullopt;
  Attempt a;
  {
    const auto lock = lock_map();
    // Local map around the keyframe the guess was registered to (the RANSAC-best candidate, not
    // the first by appearance: while tracking, that is the reference keyframe).
    a.local = build_local_map({}, guess->keyframe);
  }
  a.fit = fit_local_map(a.local, in, guess->T_world_cam.inverse(), options_.search.radius_px);
  return a;
}

Tracker::Verdict Tracker::judge(const RgbdFrame& frame, const Attempt& a, TrackResult* out) const {
  const Fit& fit = a.fit;
  if (!fit.ok || static_cast<int>(fit.inliers) < a.needed || !fit.T_cam_world.matrix().allFinite())
    return Verdict::kTooFewInliers;
  // A pose the prediction does not vouch for (lost, a stale gap, the keyframe database's) must
  // turn as the flight controller measured; a tracked fit is held to the motion bounds below.
  const bool unvouched =
      state_ != TrackingState::kTracking || out->prediction_stale || out->relocalised;
  if (unvouched && disagrees_with_attitude(frame, fit.T_cam_world.inverse()))
    return Verdict::kAttitudeDisagrees;
  if (state_ != TrackingState::kTracking) return Verdict::kAccepted;
  // While tracking, the camera cannot have moved faster than the plausible motion bounds since the
  // last tracked frame: a larger step is a wrong fit, never handed on as a pose.
  // Nor can it have left the constant-velocity path by more than the acceleration bound allows.
  const Eigen::Isometry3d step = T_world_last_.inverse() * fit.T_cam_world.inverse();
  const double dt = std::max(0.0, frame.stamp_s - last_stamp_s_);
  if (step.translation().norm() > options_.max_speed_m_per_s * dt + options_.motion_margin_m ||
      rotation_angle_rad(step) > options_.max_rate_rad_per_s * dt + options_.motion_margin_rad)
    return Verdict::kTooFast;
  const MotionBoundCheck bound =
      motion_bound_.check(frame.stamp_s, fit.T_cam_world.inverse().translation());
  if (bound.checked) {
    out->prediction_deviation_m = bound.deviation_m;
    out->prediction_deviation_bound_m = bound.bound_m;
    if (options_.motion_bound && !bound.within()) return Verdict::kOffPath;
  }
  return Verdict::kAccepted;
}

bool Tracker::confirm_off_path(const FrameInput& in, Attempt* a, TrackResult* out) {
  // The fit is strong but leaves the recent path by more than the acceleration bound allows.
  // Under fast rotation the estimated path itself is noisy (a few cm per frame on fr1_360), so
  // the bound can refuse a right fit; a wrong fit from a wrong prediction (repeated texture after
  // a stall) is what it is for. The frame is registered to the reference keyframe by descriptors
  // and 3D-3D RANSAC, independent of the prediction, and refitted there: when that lands on the
  // same pose, the fit has independent support and is kept.
  if (reference_kf_ < 0) return false;
  const auto from_keyframes = fit_from_keyframes(in, {reference_kf_});
  if (!from_keyframes) return false;
  const Fit& refit = from_keyframes->fit;
  if (!refit.ok || static_cast<int>(refit.inliers) < options_.min_inliers_relocalised) return false;
  const CameraShift d = camera_shift(a->fit.T_cam_world, refit.T_cam_world);
  out->cross_check_shift_m = d.metres;
  out->cross_check_shift_deg = d.degrees;
  const bool same_pose =
      d.metres <= options_.off_path_same_pose_m && d.degrees <= options_.off_path_same_pose_deg;
  out->off_path_confirmed = same_pose;
  return same_pose;
}

TrackResult Tracker::declare_lost(TrackResult* out) {
  // Lost: hold the last pose; the next frames go straight to relocalisation.
  state_ = TrackingState::kLost;
  have_velocity_ = false;
  out->state = TrackingState::kLost;
  out->T_world_cam = T_world_last_;
  out->reference_keyframe = reference_kf_;
  const auto lock = lock_map();
  if (auto T_kf = map_->map.resolve_pose(reference_kf_))
    out->T_kf_cam = T_kf->inverse() * T_world_last_;
  T_ref_last_ = out->T_kf_cam;
  out->map_keyframes = map_->map.keyframes().size();
  out->map_points = map_->map.points().size();
  return std::move(*out);
}

std::vector<std::int64_t> Tracker::decide_keyframe(const FrameInput& in, const Attempt& a,
                                                   const Eigen::Isometry3d& T_world_cam,
                                                   bool keyframe_allowed, bool mapper_idle,
                                                   TrackResult* out) {
  const Fit& fit = a.fit;
  std::vector<std::int64_t> matched_ids;
  std::vector<bool> matched_near;
  int near_tracked = 0, near_untracked = 0;
  for (std::size_t k = 0; k < fit.point_of_keypoint.size(); ++k) {
    const bool near = in.tf.depth_m[k] <= options_.near_depth_m;
    if (fit.point_of_keypoint[k] >= 0) {
      matched_ids.push_back(a.local.points[static_cast<std::size_t>(fit.point_of_keypoint[k])].id);
      matched_near.push_back(near);
      near_tracked += near ? 1 : 0;
    } else {
      near_untracked += near ? 1 : 0;
    }
  }
  bool make_keyframe = false;
  {
    const auto lock = lock_map();
    SlamMap& map = map_->map;
    count_visibility(a.local, fit.T_cam_world);
    std::unordered_map<std::int64_t, int> votes;
    int near_matched = 0, near_well_observed = 0;
    for (std::size_t i = 0; i < matched_ids.size(); ++i) {
      MapPoint* p = map.point(matched_ids[i]);
      if (!p) continue;
      ++p->found;
      for (const auto& [kf, kp] : p->observations) ++votes[kf];
      if (matched_near[i]) {
        ++near_matched;
        near_well_observed +=
            static_cast<int>(p->observations.size()) >= options_.redundant_observers ? 1 : 0;
      }
    }
    std::int64_t best_kf = reference_kf_;
    int best_votes = -1;
    for (const auto& [kf, n] : votes)
      if (n > best_votes || (n == best_votes && kf > best_kf)) {
        best_votes = n;
        best_kf = kf;
      }
    if (map.has_keyframe(best_kf)) reference_kf_ = best_kf;
    // ORB-SLAM2's NeedNewKeyFrame without its clock rule: the reference keyframe's points seen by
    // nMinObs observations (3, or 2 while the map has <= 2 keyframes), an RGB-D observation
    // counting 2 there: i.e. 2 keyframes, or 1 while the map has <= 2 keyframes. Ratio 0.75
    // (0.4 while there is a single keyframe).
    // A new map segment counts its own keyframes, as a new map would.
    const std::size_t kfs = segment_keyframes_ ? *segment_keyframes_ : map.keyframes().size();
    const double ratio =
        kfs < 2 ? options_.keyframe_tracked_ratio_first : options_.keyframe_tracked_ratio;
    const int ref_tracked = map.tracked_points(reference_kf_, min_observations());
    const int tracked = static_cast<int>(fit.inliers);
    const bool view_changed = tracked < ratio * ref_tracked;
    const bool need_near =
        near_tracked < options_.near_tracked_min && near_untracked > options_.near_untracked_min;
    make_keyframe = keyframe_allowed && (view_changed || need_near) && tracked > 15;
    out->keyframe_wanted = !(view_changed || need_near) || tracked <= 15 ? KeyframeReason::kNone
                           : view_changed && need_near                   ? KeyframeReason::kBoth
                           : view_changed ? KeyframeReason::kViewChanged
                                          : KeyframeReason::kNeedNear;
    // ORB-SLAM2 c1b/c1c: with the mapper busy, only weak tracking inserts (otherwise a keyframe
    // made now would wait behind the mapper while the view it was made for is already tracked
    // again).
    const bool weak = tracked < options_.keyframe_busy_tracked_ratio * ref_tracked || need_near;
    if (make_keyframe && !mapper_idle && !weak) {
      make_keyframe = false;
      out->keyframe_wanted = KeyframeReason::kMapperBusy;
    }
    if (make_keyframe && view_changed && !need_near && options_.keyframe_needs_new_content &&
        near_matched > 0) {
      out->near_redundant = static_cast<double>(near_well_observed) / near_matched;
      if (out->near_redundant >= options_.redundant_fraction) {
        make_keyframe = false;
        out->keyframe_wanted = KeyframeReason::kRedundant;
      }
    }
    out->ref_tracked = ref_tracked;
    out->near_tracked = near_tracked;
    out->near_untracked = near_untracked;
    out->reference_keyframe = reference_kf_;
    if (auto T_kf = map.resolve_pose(reference_kf_)) out->T_kf_cam = T_kf->inverse() * T_world_cam;
  }
  if (make_keyframe) {
    // The depthless keypoints a keyframe keeps are unrolled by the refitted rate, as in.tf was;
    // here rather than in the refit, since only keyframes keep them.
    const bool refitted = options_.depthless_map_points && in.depthless.size() && in.extracted &&
                          out->rolling_shutter_rate_rad_per_s;
    const TrackedFeatures depthless =
        refitted ? unrolled(*in.extracted->depthless, in, *out->rolling_shutter_rate_rad_per_s)
                 : in.depthless;
    out->keyframe_id = insert_keyframe(in.frame, in.tf, depthless, in.thumbnail, T_world_cam,
                                       a.local, fit.point_of_keypoint, fit.point_of_depthless);
    out->keyframe = true;
    out->reference_keyframe = out->keyframe_id;
    out->T_kf_cam = Eigen::Isometry3d::Identity();
  }
  return matched_ids;
}

void Tracker::count_visibility(const LocalMap& local, const Eigen::Isometry3d& T_cam_world) {
  // Visibility statistics at the refined pose (for the mapper's point culling). Map locked.
  SlamMap& map = map_->map;
  for (const LocalPoint& lp : local.points) {
    MapPoint* p = map.point(lp.id);
    if (!p) continue;
    const Eigen::Vector3d pc = T_cam_world * lp.p_world_m;
    if (pc.z() < options_.search.min_depth_m) continue;
    const Eigen::Vector3d uvd = camera_.project(pc);
    if (camera_.in_image(uvd.x(), uvd.y())) ++p->visible;
  }
}

void Tracker::advance(const RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam,
                      std::vector<std::int64_t> matched_points, bool continues_motion,
                      TrackResult* out) {
  // Motion model over the last interval (not across a relocalisation).
  const double dt = frame.stamp_s - last_stamp_s_;
  if (state_ == TrackingState::kTracking && continues_motion && dt > 0) {
    T_last_cur_velocity_ = T_world_last_.inverse() * T_world_cam;
    last_interval_s_ = dt;
    have_velocity_ = true;
    restart_motion_known_ = true;
  } else {
    have_velocity_ = false;
    restart_motion_known_ = false;
    motion_bound_.reset();
  }
  motion_bound_.add(frame.stamp_s, T_world_cam.translation());
  state_ = TrackingState::kTracking;
  T_world_last_ = T_world_cam;
  last_pose_known_ = true;
  T_ref_last_ = out->T_kf_cam;
  last_stamp_s_ = frame.stamp_s;
  last_q_nav_cam_ = frame.q_nav_cam;
  last_points_ = std::move(matched_points);
  out->state = TrackingState::kTracking;
  out->T_world_cam = T_world_cam;
}

}  // namespace rgbdquad::slam
