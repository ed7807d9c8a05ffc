// Tracking against the local map (the only stage on the camera-to-command path). Per frame:
//  1. predict the pose with a constant-velocity model scaled to the frame interval (a gap of
//     dropped frames is extrapolated, not mistaken for a stop), optionally with a rotation prior
//     (e.g. the craft's IMU attitude) replacing the predicted rotation;
//  2. build the local map: the keyframes that observed the last frame's points (most first) and
//     their covisible neighbours, bounded in count, and the points they see;
//  3. match those points by projection (wide radius), optimise the pose, match again with a narrow
//     radius around the refined projection, optimise again (motion-only, RGB-D residual);
//  4. when projection finds too little (fast rotation), after a gap longer than the prediction
//     vouches for (always: the projection fit is then kept only if it beats the database's), or
//     when tracking was lost: recover the pose from descriptor matches against keyframes ranked
//     by appearance (thumbnails) with 3D-3D RANSAC, then refine against the local map
//     (relocalisation, same map and world frame); a fit that is weak (the frame is about to
//     become a keyframe) is cross-checked the same way against the reference keyframe alone;
//  5. decide a keyframe by view change (tracked points fall below a fraction of the reference
//     keyframe's, or too few near points are tracked), never by the clock; insert it and its new
//     near points into the map for the mapper to refine.
// Thresholds follow ORB-SLAM2's RGB-D tracking (cited per field).
//
// Thread safety: one Tracker per camera stream; it locks the shared map only for short copies and
// insertions (`SharedMap::mutex`), never while extracting features or optimising.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "slam/core/lock_schedule.hpp"
#include "slam/core/thread_priority.hpp"
#include "slam/features/features.hpp"
#include "slam/map/map.hpp"
#include "slam/matching/matching.hpp"
#include "slam/motion/motion.hpp"
#include "slam/tracking/gravity_prior.hpp"
#include "slam/tracking/motion_bound.hpp"
#include "slam/tracking/pose_optimizer.hpp"
#include "slam/tracking/projection_search.hpp"
#include "slam/tracking/registration.hpp"

namespace rgbdquad::slam {

/// The map's lock. Priority inheritance: the mapper and the loop closer run below tracking (niced,
/// or SCHED_OTHER under a real-time tracker); preempted while holding the map they would keep a
/// real-time tracker waiting behind the machine's other work (p95 16 ms, max 26 ms at load 7-10).
/// With PTHREAD_PRIO_INHERIT the holder runs at the waiting tracker's real-time priority until it
/// unlocks. (Between SCHED_OTHER threads the kernel's boost does not change CFS weights: it helps
/// where tracking is real-time, as in slam-server and quad-control.)
using MapMutex = PriorityInheritanceMutex;

/// The map with the mutex that guards it; shared by the tracker, the mapper and the loop closer.
struct SharedMap {
  explicit SharedMap(bool priority_inheritance = true) : mutex(priority_inheritance) {}
  /// Locks `mutex` for one of the threads that change the map, in the order `schedule` records or
  /// replays. Readers that change nothing (checkpoints, reports) lock `mutex` directly.
  std::unique_lock<MapMutex> lock(MapParty who) {
    if (!schedule) return std::unique_lock<MapMutex>(mutex);
    schedule->before_lock(who);
    std::unique_lock<MapMutex> held(mutex);
    schedule->after_lock(who);
    return held;
  }
  MapMutex mutex;
  /// Lock-step record or replay of the threads' turns (PipelineOptions::lock_schedule_*); null:
  /// off.
  std::shared_ptr<LockSchedule> schedule;
  SlamMap map;
  /// Bumped (under `mutex`) by every loop correction that moved keyframes and points: the tracker
  /// re-anchors its last pose to its reference keyframe, the mapper drops a bundle adjustment
  /// solved on poses from before the correction.
  std::uint64_t corrections = 0;
  /// The map's gravity direction in the world frame (TrackerOptions::gravity, GravityReference):
  /// written by the tracker as keyframes add to it, read by the mapper's BA and the loop closer's
  /// pose graph for their gravity factors. Empty while gravity is off or not yet measured.
  std::optional<Eigen::Vector3d> gravity_down_world;
};

/// Why the keyframe rule asked for a keyframe (logged per frame; see Tracker::track step 5).
/// kRedundant: the view changed, but the map already sees this view from enough keyframes (a
/// revisit): the keyframe would be culled as redundant at once, so none was made.
/// kMapperBusy: the view changed, but the mapper was still busy and tracking was not weak
/// (ORB-SLAM2 NeedNewKeyFrame c1b/c1c): the keyframe is left to a later frame.
enum class KeyframeReason {
  kNone,
  kFirst,
  kViewChanged,
  kNeedNear,
  kBoth,
  kRedundant,
  kMapperBusy
};
const char* to_string(KeyframeReason r);

struct TrackerOptions {
  ProjectionSearchOptions search;  ///< first pass: radius 15 px (ORB-SLAM2 motion model)
  double refine_radius_px =
      3.0;  ///< second pass around the refined pose (ORB-SLAM2: 3 after relocalisation, 1
            ///< otherwise; 3 tolerates our coarser ORB levels)
  double wide_radius_factor = 3.0;  ///< when the first pass finds too little (gaps)
  PoseOptimizerOptions pose;
  int min_matches_first_pass = 20;       ///< ORB-SLAM2 TrackWithMotionModel: < 20 -> wider search
  int min_inliers_tracking = 30;         ///< ORB-SLAM2 TrackLocalMap: >= 30 inliers
  int min_inliers_relocalised = 50;      ///< ORB-SLAM2 Relocalization / after it: >= 50
  int max_local_keyframes = 30;          ///< bounds the per-frame cost (ORB-SLAM2: 80)
  int covisible_per_keyframe = 10;       ///< ORB-SLAM2 UpdateLocalKeyFrames: best 10 neighbours
  double keyframe_tracked_ratio = 0.75;  ///< ORB-SLAM2 RGB-D thRefRatio
  double keyframe_tracked_ratio_first =
      0.4;  ///< ORB-SLAM2 thRefRatio while the map has one keyframe
  /// While the mapper is busy (ORB-SLAM2 NeedNewKeyFrame c1b false) only weak tracking makes a
  /// keyframe: inliers < this x the reference keyframe's tracked points (c1c: 0.25), or the near
  /// rule.
  double keyframe_busy_tracked_ratio = 0.25;
  double near_depth_m = 3.1;    ///< ORB-SLAM2 ThDepth: 40 baselines of the Kinect (bf 40 / fx 517)
  int near_tracked_min = 100;   ///< ORB-SLAM2 bNeedToInsertClose: < 100 near tracked...
  int near_untracked_min = 70;  ///< ...and > 70 near untracked -> keyframe
  int min_new_points = 100;     ///< ORB-SLAM2 CreateNewKeyFrame: at least the 100 nearest
  int min_init_features = 100;  ///< a first keyframe needs this many features with depth
  /// Revisits: a view change alone does not make a keyframe that the mapper's culling would judge
  /// redundant at once - when >= `redundant_fraction` of the frame's tracked near points are
  /// already observed by >= `redundant_observers` keyframes (ORB-SLAM2 KeyFrameCulling's test, the
  /// same values as LocalMapperOptions). Without it, a revisited place keeps getting keyframes that
  /// the culling then removes. Weak tracking (the near rule) still inserts.
  bool keyframe_needs_new_content = true;
  double redundant_fraction = 0.9;
  int redundant_observers = 3;
  std::size_t relocalisation_candidates = 4;  ///< keyframes tried, by appearance
  MatchOptions matching;               ///< descriptor matching for relocalisation (thesis NNMMT...
  double relocalisation_ratio = 0.75;  ///< ...with ORB-SLAM2's Relocalization ratio: views far
                                       ///< apart match fewer pairs than consecutive frames)
  int min_relocalisation_ransac_inliers = 10;  ///< a guess only (ORB-SLAM2: 10 PnP inliers); the
                                               ///< local-map refit needs min_inliers_relocalised
  RansacOptions ransac;                        ///< 3D-3D RANSAC for relocalisation (thesis values)
  /// Motion bounds between two tracked frames: an indoor quadcopter (and a hand-held Kinect in the
  /// TUM sequences, 0.4 m/s and 40 deg/s on average) stays well below 2 m/s and 180 deg/s; a pose
  /// step beyond them plus a margin for estimation noise is a wrong fit (tracking is declared
  /// lost).
  double max_speed_m_per_s = 2.0;
  double max_rate_rad_per_s = 3.14159;
  double motion_margin_m = 0.05;
  double motion_margin_rad = 0.0873;  ///< 5 deg
  /// Bound on the deviation of a tracked position from the recent constant-velocity path over the
  /// gap dt (MotionBound: motion_margin_m + a dt (dt + baseline) / 2). 5 m/s^2: the TUM ground
  /// truth deviates from constant velocity at most 88.6 mm over 260 ms on fr1_xyz (~2.6 m/s^2),
  /// 248.9 mm over 500 ms, 68.3 mm over 260 ms on fr2_desk; a craft tilted 27 deg accelerates
  /// 5 m/s^2 horizontally, past what an indoor waypoint flight commands. Unlike the speed bound it
  /// stays tight on short gaps: 0.27 m at 260 ms, where a 0.32 m wrong fit was accepted in a `make
  /// demo-loop` run. Needs two tracked positions since the last relocalisation or loop correction.
  double max_acceleration_m_per_s2 = 5.0;
  double motion_bound_baseline_s = 0.1;  ///< MotionBoundOptions::baseline_s
  bool motion_bound = true;              ///< false: the bound is computed and logged, not enforced
  /// Keypoints without a depth reading (FrameFeatures::depthless) are matched to map points by
  /// projection and enter the pose fit as (u, v) observations, as ORB-SLAM2 observes its
  /// monocular keypoints: where the view's far half is beyond the depth range (a far wall) or
  /// its corners sit on depth holes at occluding edges, those points still fix the rotation,
  /// which the near points alone leave ambiguous against the position. Their count is reported
  /// apart; every inlier bar stays on the matches with depth.
  bool depthless_observations = true;
  /// Keyframes keep their depthless keypoints (and the matches tracking made to them), so that
  /// the mapper can triangulate map points from them (LocalMapperOptions::triangulate_depthless):
  /// the far wall that no depth reading reaches gets points for the observations above to match.
  /// Needs depthless_observations. On: the first lap of five HIL flights drifts 12.8 instead of
  /// 16.5 mm (mean) and the real fast turn scores better over a spread of runs (docs/slam.md).
  bool depthless_map_points = true;
  double max_velocity_scale =
      5.0;  ///< a gap of more than 5 frame intervals is not extrapolated further
  /// Beyond this gap since the last tracked frame the prediction no longer vouches for the pose:
  /// the projection fit must then meet the relocalisation bar (`min_inliers_relocalised`), as
  /// ORB-SLAM2 demands 50 inliers right after a relocalisation, and below it the keyframe database
  /// is tried. 0.2 s: 6 frame intervals at 30 fps, just past what `max_velocity_scale`
  /// extrapolates; over 0.2 s the TUM fr1 camera moves up to ~7 cm, the HIL craft at waypoint speed
  /// ~10 cm: enough for a projection search at the wrong offset in a room of repeated texture to
  /// reach the tracking bar (HIL scenario 4, 1.7 s link stall: a 45-inlier fit 0.4 m off).
  double max_predicted_gap_s = 0.2;
  /// A fit that passes the tracking bar but is weak - fewer inliers than this x the reference
  /// keyframe's tracked points, or fewer than `min_inliers_relocalised` - is cross-checked: the
  /// frame is registered to the reference keyframe by descriptors and 3D-3D RANSAC, independent of
  /// the prediction, refitted against the local map around it, and the fit with more inliers is
  /// kept. 0.75 is the keyframe rule's `keyframe_tracked_ratio`: such a frame is about to become a
  /// keyframe, and a keyframe made at a wrong pose misplaces every point it adds and every frame
  /// tracked against them. On fr1_xyz_first300 with every 4th frame (7.5 fps: 5 cm and 2-3 deg
  /// between frames, like a 30 fps stream with dropped frames) a constant-velocity prediction past
  /// a change of direction converged 5 deg and 7 cm off with 183 inliers; the keyframe made there
  /// put the next 8 frames 0.1 m off. 0 disables the cross-check.
  double cross_check_tracked_ratio = 0.75;
  /// The cross-check's fit replaces the projection fit only at a different pose: within these the
  /// two are one solution and the projection fit stays (with the local map of the last frame's
  /// points, so a keyframe made here keeps its links to the map). Measured on fr1_xyz_first300
  /// (every 1st-6th frame): fits of one pose differed by 0.1-8 mm and <= 0.6 deg, the wrong fits
  /// the cross-check caught by 15-240 mm and 0.3-8.7 deg. (In a HIL flight at 30 fps every
  /// cross-check landed within 1.4 mm: nothing is replaced there.)
  double cross_check_same_pose_m = 0.01;
  double cross_check_same_pose_deg = 0.5;
  /// Predict the rotation from the caller's attitude (`RgbdFrame::q_nav_cam`) when two consecutive
  /// frames carry one: an IMU measures rotation directly, where the constant-velocity model
  /// extrapolates the last interval's (wrong at every change of turn rate, and across gaps).
  bool attitude_prior = true;
  /// When a frame can be neither tracked nor relocalised, start a new map segment at once at the
  /// predicted pose (the frame's near points become a keyframe) instead of holding the last pose
  /// until the camera returns to mapped ground: a craft turning or flying into unmapped space
  /// keeps a pose and a local map. The segment lives in the same map and world frame and is moved
  /// onto the older map when its place is recognised (segment_merge_period_s). On by default: a
  /// fast turn into new ground (fr1_360_first60) loses no frame with it and 35 of 60 without;
  /// sequences that never fail are unchanged (fr1_xyz_first300, fr2_desk_first50, identical
  /// trajectories); a 10-minute HIL flight and the fast-manoeuvre HIL scenario pass with it.
  /// Without the merge it fragmented a 10-minute HIL flight into 3 segments (15-37 mm a minute).
  bool restart_when_lost = true;
  /// A segment's first keyframe needs this many features with depth: the next frame must find the
  /// tracking bar (min_inliers_tracking, 30) among them after the matches a turn loses (ORB-SLAM2
  /// keeps about 2/3 of its matches between fast frames), so 50 - the relocalisation bar. The
  /// map's very first keyframe keeps min_init_features.
  int min_segment_features = 50;
  /// A frame after a gap the prediction no longer vouches for (max_predicted_gap_s: a link stall,
  /// a run of dropped frames, a blank stretch) that neither the stale projection fit nor the
  /// keyframe database can place starts a new segment too (with restart_when_lost), instead of
  /// holding the last pose until the camera sees mapped ground again: a craft that stalled while
  /// turning into unmapped space hovers there in lost-hold, and relocalisation cannot find what
  /// the map never saw (seen in the soak: after a 0.95 s stall every frame stayed lost until the
  /// 2 s lost-hold ran out). Its pose is a guess - the prediction (at most max_velocity_scale
  /// intervals of the last velocity), turned by the attitude's change when both frames carry
  /// one - so the segment is declared as a map correction: a consumer takes the jump from its
  /// own estimate as the world frame moving, not the craft (as after a loop correction), and the
  /// merge declares the next one. Needs a tracked frame in this run (not after a map load).
  bool restart_after_gap = true;
  /// A pose that the motion model does not vouch for - from the keyframe database, after a stale
  /// gap, or a segment merge - is refused when its rotation since the last tracked frame
  /// disagrees with the attitude's change (RgbdFrame::q_nav_cam, both frames) by more than this.
  /// The flight controller's attitude is filtered to about a degree in roll and pitch, and its
  /// yaw (gyro and compass) drifts a few degrees over the gaps the craft sees (seconds); a place
  /// recognised in the wrong part of a room of repeated texture is off by tens of degrees (the
  /// soak: 84 deg, refused only by quad-control's jump gate after the lost-hold ran out). 0: off.
  /// Frames without an attitude (TUM, hand-held) are never judged by it.
  double max_attitude_disagreement_deg = 10.0;
  /// While a segment is not yet joined to the map before it, every `segment_merge_period_s` the
  /// tracked frame is also relocalised against the keyframes older than the segment (appearance
  /// ranking, registration, local-map refit to the relocalisation bar); when that succeeds the
  /// whole segment - keyframes and points - is moved rigidly onto the older map (ORB-SLAM3's Atlas
  /// merges maps on place recognition; a segment a few frames old is rigid enough to move as
  /// one). 0.2 s: a relocalisation costs 10-30 ms on 2 cores, so trying ~5 times a second adds
  /// a few ms per frame on average, and a craft back over mapped ground is merged within 0.2 s.
  double segment_merge_period_s = 0.2;
  /// A fit with enough inliers that only the motion bound refuses, within max_predicted_gap_s of
  /// the last tracked frame, is checked, not dropped: it is kept when the frame's registration to
  /// the reference keyframe (descriptors + 3D-3D RANSAC, refitted on the local map, >=
  /// min_inliers_relocalised) lands within the same-pose tolerance below. The tolerance is the
  /// cross-check's: fits of one pose differ by up to 8 mm and 0.6 deg on fr1_xyz_first300, wrong
  /// fits by 15 mm and more; 2 cm and 1 deg leave room for the noisier fits of a fast turn.
  /// On by default: the bound's wrong fits came after gaps the prediction no longer vouched for
  /// (there it stays final), and the alternative to a confirmed fit, a new map segment at the
  /// predicted pose, is further off: in a fast turn (fr1_360_first60) the bound refused fits of
  /// 80-170 inliers that the registration confirmed, and each refusal started a segment (8 where
  /// 2 remain with the check).
  bool confirm_off_path = true;
  double off_path_same_pose_m = 0.02;
  double off_path_same_pose_deg = 1.0;
  /// Re-time each frame's depth to its colour image (RgbdFrame::depth_stamp_s) by the predicted
  /// rotation before features are lifted to 3D (slam/tracking/depth_time_alignment.hpp).
  bool align_depth_time = false;
  /// How long after the colour image's exposure its stamp was taken (align_depth_time re-times the
  /// depth to the exposure). 0: the stamp is the exposure.
  double colour_stamp_lag_s = 0.0;
  /// Rolling-shutter readout time of the camera, seconds top row to bottom row (0: treat it as a
  /// global shutter; the cameras' values: protocol/camera/tum_cameras.json). Matching uses the
  /// features rotated to the middle row's time by the motion model's rate; the accepted pose is
  /// then refitted with the rate over the readout as three more unknowns (RollingShutterModel),
  /// and the frame keeps its features rotated by that rate (slam/tracking/rolling_shutter.hpp).
  double rolling_shutter_readout_s = 0.0;
  /// How fast the camera's rate changes, rad/s^2: the refit's rate is held near the motion
  /// model's with sigma = this x the motion model's age at the frame (from the middle of its last
  /// interval to the frame's stamp; 50 ms at 30 fps). The rows of one frame measure the rate only
  /// to 0.4 rad/s rms on slow hand-held motion and 1.2 rad/s on a fast turn (rolling_shutter_check
  /// against the mocap), so the prior carries most of it. 3 rad/s^2: TUM's hand-held fr1/fr2
  /// motion capture changes its rate by 0.11-0.23 rad/s per axis rms over 50 ms (an upper bound:
  /// it includes the mocap's own noise); a craft reaching a 60 deg/s yaw in 0.3 s needs 3.5. A
  /// calibration run (rolling_shutter_check.py) widens it so that the rate is the rows' alone.
  double rolling_shutter_angular_accel_rad_per_s2 = 3.0;
  /// Gravity's direction as a roll/pitch prior in the pose fit (slam/tracking/gravity_prior.hpp).
  GravityOptions gravity;
  bool is_valid(std::string* error) const;
};

struct TrackResult {
  TrackingState state = TrackingState::kInitialising;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  std::int64_t reference_keyframe = -1;
  Eigen::Isometry3d T_kf_cam = Eigen::Isometry3d::Identity();
  bool keyframe = false;          ///< this frame became a keyframe `keyframe_id`
  std::int64_t keyframe_id = -1;  ///< the frame index, unless a loaded map already uses it
  bool relocalised = false;       ///< the pose came from the keyframe database, not the prediction
  /// Neither tracking nor relocalisation gave a pose: the frame started a new map segment at the
  /// predicted pose (TrackerOptions::restart_when_lost); `state` is kTracking.
  bool new_segment = false;
  /// The frame's relocalisation joined the current segment to the map before it (the segment
  /// moved by a rigid correction; map_corrections counts it).
  bool segment_merged = false;
  /// A pose was refused because its rotation disagreed with the frame's attitude
  /// (TrackerOptions::max_attitude_disagreement_deg): a relocalisation or a segment merge.
  bool attitude_refused = false;
  bool gravity_prior = false;  ///< the pose fit had a gravity prior (TrackerOptions::gravity)
  /// The camera's angular velocity over the readout the rolling-shutter refit estimated (camera
  /// frame, rad/s); empty for a global shutter or when the refit was not made.
  std::optional<Eigen::Vector3d> rolling_shutter_rate_rad_per_s;
  /// The fit left the motion bound but a registration to the reference keyframe confirmed it
  /// (TrackerOptions::confirm_off_path).
  bool off_path_confirmed = false;
  /// The fit was weak and was cross-checked against the reference keyframe
  /// (TrackerOptions::cross_check_tracked_ratio); `relocalised` too when the cross-check's fit won.
  bool cross_checked = false;
  /// How far the cross-check's fit was from the projection fit (-1: no cross-check fit).
  double cross_check_shift_m = -1, cross_check_shift_deg = -1;
  bool attitude_predicted = false;  ///< the predicted rotation came from RgbdFrame::q_nav_cam
  bool prediction_stale =
      false;  ///< the gap since the last tracked frame exceeded max_predicted_gap_s
  /// Distance of the fitted position from the recent constant-velocity path, and its bound
  /// (MotionBound); -1 when not checked.
  double prediction_deviation_m = -1, prediction_deviation_bound_m = -1;
  std::size_t local_points = 0;  ///< points in the local map this frame was matched against
  std::size_t matches = 0;       ///< projection matches before the final optimisation
  std::size_t inliers = 0;
  /// Inliers among the keypoints without depth (TrackerOptions::depthless_observations).
  std::size_t depthless_inliers = 0;
  double local_map_ms = 0, search_ms = 0, optimise_ms = 0, relocalise_ms = 0;
  /// Wall time this frame spent waiting to acquire the map lock (all acquisitions summed): what a
  /// mapper or loop closer holding it costs the camera-to-command path.
  double map_lock_wait_ms = 0;
  std::size_t map_keyframes = 0, map_points = 0;  ///< map size after this frame
  /// The keyframe rule's verdict and inputs (also when the keyframe was deferred: `keyframe`
  /// false).
  KeyframeReason keyframe_wanted = KeyframeReason::kNone;
  int ref_tracked = 0, near_tracked = 0, near_untracked = 0;
  double near_redundant =
      -1;  ///< fraction of tracked near points seen by >= 3 keyframes (-1: not computed)
  /// SharedMap::corrections this pose is expressed after: a change from the previous frame's
  /// declares that a loop correction moved the world frame under the craft in between.
  std::uint64_t map_corrections = 0;
};

/// How far apart two poses of one camera are: the distance between the camera centres and the
/// angle between the orientations.
struct CameraShift {
  double metres = 0, degrees = 0;
};
CameraShift camera_shift(const Eigen::Isometry3d& T_cam_world_a,
                         const Eigen::Isometry3d& T_cam_world_b);

/// The projection-fit settings inside the tracker options.
ProjectionFitOptions projection_fit_options(const TrackerOptions& options);

/// What the mapper can take while frames are tracked (the pipeline's bounded keyframe queue:
/// keyframe_admission in local_map_system.hpp). All true when the caller waits for mapping.
struct KeyframeAdmission {
  bool allowed = true;      ///< a keyframe may be made
  bool mapper_idle = true;  ///< false: only weak tracking makes one
  /// A failing frame may start a map segment (TrackerOptions::restart_when_lost); the only
  /// alternative is a lost frame, so its bound is looser than `allowed`'s.
  bool segment_start_allowed = true;
  /// The mapper takes nothing: no keyframe, no segment start.
  static KeyframeAdmission none() { return {false, false, false}; }
};

class Tracker {
 public:
  static std::optional<Tracker> create(const TrackerOptions& options, const CameraModel& camera,
                                       std::shared_ptr<SharedMap> map, std::string* error);

  /// Tracks one frame whose features are extracted; `admission`: what the mapper can take now.
  /// When this frame and the last tracked one both carry `RgbdFrame::q_nav_cam` (and
  /// `TrackerOptions::attitude_prior` is on), the predicted rotation is the last pose's rotated by
  /// the attitude's change between the two frames instead of the constant-velocity rotation.
  TrackResult track(const RgbdFrame& frame, std::shared_ptr<const FrameFeatures> features,
                    const FeatureOptions& feature_options, KeyframeAdmission admission = {});

  /// The camera's angular velocity (camera frame, rad/s) the motion model predicts for the next
  /// frame; nullopt while it has none (initialising, lost, after a relocalisation).
  std::optional<Eigen::Vector3d> predicted_rotation_rate_rad_per_s() const;

  /// Forget the motion model and start from relocalisation (after a map load, or a reset).
  void set_lost() {
    state_ = TrackingState::kLost;
    restart_motion_known_ = false;
    last_pose_known_ = false;
  }
  TrackingState state() const { return state_; }

 private:
  Tracker(TrackerOptions options, CameraModel camera, std::shared_ptr<SharedMap> map)
      : options_(std::move(options)),
        camera_(camera),
        map_(std::move(map)),
        motion_bound_(MotionBoundOptions{options_.motion_margin_m,
                                         options_.max_acceleration_m_per_s2,
                                         options_.motion_bound_baseline_s}),
        gravity_reference_(options_.gravity.init_keyframes) {}

  struct LocalMap {
    std::vector<LocalPoint> points;
    std::vector<std::int64_t> keyframes;
  };
  using Fit = ProjectionFit;
  /// One frame as the steps of track() see it.
  struct FrameInput {
    const RgbdFrame& frame;
    TrackedFeatures tf;
    cv::Mat thumbnail;
    std::uint64_t seed = 0;  ///< RANSAC seed of this frame's relocalisation
    /// The features as extracted, before any rolling-shutter correction (set when the camera
    /// has a rolling shutter, TrackerOptions::rolling_shutter_readout_s).
    std::shared_ptr<const FrameFeatures> extracted;
    const FeatureOptions* feature_options = nullptr;
    /// Keypoints without depth (TrackerOptions::depthless_observations; empty when off), rotated
    /// by the predicted rate like `tf` before the first fit.
    TrackedFeatures depthless;
  };
  /// The pose fit under way: the local map it was matched against and the inliers it needs.
  struct Attempt {
    LocalMap local;
    Fit fit;
    int needed = 0;
  };

  // The steps of track(), in order.
  TrackResult track_steps(FrameInput& in, KeyframeAdmission admission);
  /// Rolling shutter: the frame's features rotated to the middle row's time by the rotation
  /// rate `omega_cam_rad_per_s`, from the features as extracted.
  TrackedFeatures unrolled(const FrameInput& in, const Eigen::Vector3d& omega_cam_rad_per_s) const;
  /// The same for other features of the frame (its depthless keypoints).
  TrackedFeatures unrolled(const FrameFeatures& extracted, const FrameInput& in,
                           const Eigen::Vector3d& omega_cam_rad_per_s) const;
  /// Rolling shutter: refits the accepted pose on its inlier matches with the camera's angular
  /// velocity over the readout as three more unknowns (RollingShutterModel), and keeps the
  /// frame's features unrolled by that rate.
  void refit_rolling_shutter(FrameInput* in, Attempt* a, TrackResult* out) const;
  /// The pose fit's options for this frame (with its gravity prior, if any).
  ProjectionFitOptions frame_fit_options() const;
  /// The first keyframe of an empty map, at the origin.
  TrackResult initialise(const FrameInput& in);
  /// Re-anchors the last pose when a loop correction moved its reference keyframe.
  void follow_map_corrections(TrackResult* out);
  /// Constant-velocity prediction over the gap, with the attitude prior's rotation if any.
  Eigen::Isometry3d predict(const RgbdFrame& frame, TrackResult* out) const;
  /// Builds the local map and fits the pose to it by projection from the prediction.
  Attempt search_local_map(const FrameInput& in, const Eigen::Isometry3d& T_world_pred,
                           TrackResult* out);
  /// Relocalises when the fit is missing or weak, or cross-checks a weak fit against the
  /// reference keyframe; replaces the fit when the keyframe database's is better.
  void recover_or_cross_check(const FrameInput& in, Attempt* attempt, TrackResult* out);
  /// The frame registered to `candidates` by descriptors and 3D-3D RANSAC (independent of the
  /// prediction), then fitted by projection to the local map around the keyframe that won;
  /// nullopt when no candidate registers. Used by relocalisation, the cross-check of weak fits and
  /// confirm_off_path.
  std::optional<Attempt> fit_from_keyframes(const FrameInput& in,
                                            const std::vector<std::int64_t>& candidates) const;
  enum class Verdict { kAccepted, kTooFewInliers, kAttitudeDisagrees, kTooFast, kOffPath };
  /// Whether the fit meets its inlier bar, the attitude (for a pose the prediction does not
  /// vouch for), the speed bounds and the motion bound (in that order).
  Verdict judge(const RgbdFrame& frame, const Attempt& attempt, TrackResult* out) const;
  /// The rotation of `T_world_cam` disagrees with the last tracked pose turned by the attitude's
  /// change (TrackerOptions::max_attitude_disagreement_deg); false when either frame has none.
  bool disagrees_with_attitude(const RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam) const;
  /// The last tracked pose turned by the attitude's change since (unchanged without attitudes).
  Eigen::Matrix3d attitude_rotation(const RgbdFrame& frame) const;
  /// A fit refused by the motion bound alone is kept when a registration to the reference
  /// keyframe, independent of the prediction, lands on the same pose
  /// (TrackerOptions::confirm_off_path).
  bool confirm_off_path(const FrameInput& in, Attempt* attempt, TrackResult* out);
  /// Holds the last pose; the next frames relocalise.
  TrackResult declare_lost(TrackResult* out);
  /// Where a new map segment starts (TrackerOptions::restart_when_lost), or nullopt when the
  /// frame cannot start one (too few features, the mapper's queue full, no pose known in this
  /// run). `after_gap`: the pose is a guess past max_predicted_gap_s (restart_after_gap).
  struct RestartPose {
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    bool after_gap = false;
  };
  std::optional<RestartPose> restart_pose(const FrameInput& in, bool segment_start_allowed) const;
  /// TrackerOptions::segment_merge_period_s: relocalises the tracked frame (pose T_world_cam in
  /// the segment) against the map before the segment and, on success, moves the segment onto it.
  void merge_segment(const FrameInput& in, TrackResult* out);
  /// TrackerOptions::restart_when_lost: a new map segment at `T_world_guess`.
  TrackResult start_segment(const FrameInput& in, const RestartPose& start, TrackResult out);
  /// Updates point statistics and the reference keyframe, applies the keyframe rule (inserting
  /// the keyframe); returns the map points the frame matched.
  std::vector<std::int64_t> decide_keyframe(const FrameInput& in, const Attempt& attempt,
                                            const Eigen::Isometry3d& T_world_cam,
                                            bool keyframe_allowed, bool mapper_idle,
                                            TrackResult* out);
  /// Counts the local points in view at the fitted pose (map locked by the caller).
  void count_visibility(const LocalMap& local, const Eigen::Isometry3d& T_cam_world);
  /// The frame is tracked: motion model, motion bound and last-frame state move on to it.
  /// `continues_motion`: the pose follows on from the last tracked frame's (not a relocalisation),
  /// so the step between them is the camera's motion.
  void advance(const RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam,
               std::vector<std::int64_t> matched_points, bool continues_motion, TrackResult* out);
  /// Local keyframes and their points (locks the map). `seed_points`: points of the last frame.
  LocalMap build_local_map(const std::vector<std::int64_t>& seed_points,
                           std::int64_t fallback_kf) const;
  /// Two-pass projection matching and pose optimisation from a pose guess.
  Fit fit_local_map(const LocalMap& local, const FrameInput& in,
                    const Eigen::Isometry3d& T_cam_world_guess, double first_radius_px) const;
  /// The fit passed the tracking bar but is weak (TrackerOptions::cross_check_tracked_ratio).
  bool cross_check_needed(const Fit& fit) const;
  /// A pose guess from the keyframe database and the keyframe it was registered to.
  struct KeyframeGuess {
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    std::int64_t keyframe = -1;
  };
  /// Pose from descriptor matches against the candidate keyframes' map points (3D-3D RANSAC): the
  /// candidate with the most RANSAC inliers wins (its local map seeds the refit).
  std::optional<KeyframeGuess> pose_from_keyframes(const TrackedFeatures& frame,
                                                   const std::vector<std::int64_t>& candidates,
                                                   std::uint64_t seed) const;
  /// Inserts the keyframe and its new points; returns its id.
  /// `depthless` and `point_of_depthless` are kept only with depthless_map_points.
  std::int64_t insert_keyframe(const RgbdFrame& frame, const TrackedFeatures& tf,
                               const TrackedFeatures& depthless, const cv::Mat& thumbnail,
                               const Eigen::Isometry3d& T_world_cam, const LocalMap& local,
                               const std::vector<int>& point_of_keypoint,
                               const std::vector<int>& point_of_depthless);

  /// Locks the map, adding the wait to `lock_wait_ms_` (reset per frame by track()).
  std::unique_lock<MapMutex> lock_map() const;

  TrackerOptions options_;
  CameraModel camera_;
  mutable double lock_wait_ms_ = 0;
  std::shared_ptr<SharedMap> map_;
  TrackingState state_ = TrackingState::kInitialising;
  Eigen::Isometry3d T_world_last_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_last_cur_velocity_ =
      Eigen::Isometry3d::Identity();  ///< motion over one interval
  double last_stamp_s_ = 0, last_interval_s_ = 0;
  std::optional<Eigen::Quaterniond> last_q_nav_cam_;  ///< the last tracked frame's attitude
  bool have_velocity_ = false;
  /// The velocity of the last tracked frame still predicts the pose (kept across a loss, unlike
  /// have_velocity_; false after a relocalisation or set_lost()).
  bool restart_motion_known_ = false;
  /// A frame was tracked in this run (T_world_last_ is a pose, not the origin of a loaded map).
  bool last_pose_known_ = false;
  std::vector<std::int64_t> last_points_;  ///< map points matched in the last tracked frame
  std::int64_t reference_kf_ = -1;
  Eigen::Isometry3d T_ref_last_ =
      Eigen::Isometry3d::Identity();  ///< last pose relative to reference_kf_
  std::uint64_t corrections_seen_ =
      0;                      ///< SharedMap::corrections when T_world_last_ was last anchored
  MotionBound motion_bound_;  ///< tracked positions since the last relocalisation or correction
  GravityReference gravity_reference_;
  /// This frame's gravity measurement (set by track(); TrackerOptions::gravity).
  std::optional<GravityObservation> frame_gravity_;
  /// Keyframes of the current map segment, once one was started (restart_when_lost).
  std::optional<std::size_t> segment_keyframes_;
  /// First keyframe id of the current segment while it is not joined to the map before it.
  std::optional<std::int64_t> segment_first_kf_;
  double last_merge_try_s_ = 0.0;
  /// ORB-SLAM2's nMinObs for the reference keyframe's tracked points (map locked by the caller).
  int min_observations() const;
};

}  // namespace rgbdquad::slam
