// The SLAM pipeline: front-end and back-end joined by bounded hand-over slots. This is the only
// place with threads (house style: stages are plain classes; threading lives in pipeline/).
//
// Modes:
//  - kSequential: submit() runs front-end and back-end on the caller's thread (tests);
//  - kWait: front-end thread + back-end thread, every frame goes through both, in order; the
//    back-end result of frame i is what the output holds, so results equal kSequential's
//    (deterministic; used for evaluation). The two threads overlap across consecutive frames.
//  - kRealtime: submit() never blocks: a frame arriving while the front-end still holds an
//    unprocessed one replaces it (counted as a dropped front-end frame); the back-end always takes
//    the latest front-end output and skips the rest (counted). Poses of skipped frames are the
//    front-end's odometry mapped through the latest back-end correction.
//
// With BackendKind::kLocalMap the front-end thread runs feature extraction and the Tracker (pose
// against the local map, the camera-to-command path), the back-end thread runs the LocalMapper
// on keyframes and a third thread the LoopCloser on each mapped keyframe (wait mode waits for
// both, sequential mode runs both inline). wait: the tracker waits for each keyframe to be mapped
// (deterministic, equals sequential); realtime: keyframes queue for the mapper (see
// keyframe_admission: beyond kMaxQueuedKeyframes only weak tracking adds one, up to
// kMaxQueuedKeyframesWeak), tracking never waits for mapping.
//
// Thread safety: submit()/finish() from one producer thread; results after finish().
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "slam/localmap/local_mapper.hpp"
#include "slam/localmap/loop_closer.hpp"
#include "slam/localmap/tracker.hpp"
#include "slam/pipeline/backend.hpp"
#include "slam/pipeline/frontend.hpp"
#include "slam/pipeline/thread_priority.hpp"

namespace slam {

/// kLive: submit() tracks on the caller's thread (the frame's pose is final when it returns) while
/// the local map is refined on the mapping thread - for servers that answer every frame
/// (slam-server). For the thesis back-ends kLive behaves as kSequential.
enum class PipelineMode { kSequential, kWait, kRealtime, kLive };
bool parse_pipeline_mode(const std::string& name, PipelineMode* out, std::string* error);
const char* to_string(PipelineMode m);

struct PipelineOptions {
  FrontendOptions frontend;
  BackendOptions backend;
  PipelineMode mode = PipelineMode::kWait;
  /// Refine every RANSAC estimate on the reprojection error (RansacOptions::reprojection_camera is
  /// filled from the intrinsics when true).
  bool reprojection_refine = true;
  TrackerOptions tracker;  ///< BackendKind::kLocalMap only
  /// BackendKind::kLocalMap: sigma of the depth (disparity) residual (see DepthNoiseModel).
  DepthNoiseModel depth_noise = DepthNoiseModel::kKeypointSigma;
  /// BackendKind::kLocalMap: the map lock inherits the priority of a waiting real-time tracker
  /// (SharedMap / MapMutex); false only to measure what it changes.
  bool map_lock_priority_inheritance = true;
  /// kRealtime: scheduling of the tracking thread (slam-server and quad-control raise theirs; off
  /// leaves it as created). Lets `slam-eval --mode realtime` measure the real-time path.
  ThreadPolicy tracking_thread_policy = ThreadPolicy::kOff;
  /// kRealtime/kLive, local map: when tracking runs under a real-time policy (asked above, or
  /// inherited from a real-time creator: slam-server), the mapping thread runs SCHED_RR at this
  /// priority, below the camera-to-command path (10, quad-control's firmware link 12) and above
  /// all normal work; 0 keeps it on the normal policy at a nice below its creator. Why not nice:
  /// Linux shares the CPU between processes (autogroups, systemd cgroups) before it looks at a
  /// thread's nice, so beside a CPU load in another session the mapper got 1/4.85 of its wall time
  /// (slam-eval realtime on fr1_xyz, stress-ng --cpu 2 under setsid) and in a fresh-clone demo
  /// 1/13, until tracking ran out of keyframes and was lost. Its cost is bounded per keyframe (the
  /// local window) and it yields its backlog (LocalMapper's catch-up), so it cannot hold a core.
  int mapping_rt_priority = 5;
  LocalMapperOptions mapper;  ///< BackendKind::kLocalMap only
  /// BackendKind::kLocalMap: loop closing on its own thread (binary descriptors only: the
  /// vocabulary is ORB's; with SIFT/SURF it stays off and PipelineSummary says so). On by default
  /// since session 6: with ORB-SLAM2's temporal consistency and the odometry-consistency gate
  /// (loop/loop_consistency.hpp) the replayed 18:28 HIL flight that accepted 4 loops (2 wrong,
  /// ATE 0.398 m) accepts its 1 true loop and refuses the wrong one (ATE 0.0069 m), and the
  /// 10-minute HIL flight with loop closing on flew and landed (docs/hil.md); the TUM excerpts
  /// are unchanged (no loop accepted there).
  bool loop_closing = true;
  /// kRealtime/kLive: ORB-SLAM2's c1b/c1c gate - while the mapper is busy only weak tracking makes
  /// a keyframe. Off by default: with it on, the HIL 10-minute flight on an idle machine drifted
  /// (ATE 0.109 m, loop closing off) or accepted a wrong loop correction (0.73 m, loop closing on);
  /// with it off the same build flew 4 minutes at SLAM error 6-8 mm (docs/hil.md). Our mapper runs
  /// niced below a real-time tracker, so "busy" is most of the time in flight, and the gate then
  /// withholds the keyframes the map needs; ORB-SLAM2's mapper is not starved that way.
  bool keyframe_gate_mapper_busy = false;
  LoopCloserOptions
      loop;  ///< matching, RANSAC and projection settings are filled in from the tracker's
  /// BackendKind::kLocalMap: map checkpoints. When set, the map (with its count of loop
  /// corrections) is written here - through a temporary file renamed into place - after a mapped
  /// keyframe when `checkpoint_period_s` of data have passed since the last checkpoint or a loop
  /// correction moved the map since, and once more by finish(). A service restarted after a crash
  /// loads it and continues in the same map and world frame (slam-server --checkpoint-dir). The
  /// map is copied under the map lock (the tracker waits for the copy only) and written by the
  /// thread that finished the keyframe (loop closing, else mapping), never the tracking thread.
  std::string checkpoint_path;
  /// 1 s: a restarted service can relocalise only where the checkpoint has keyframes, and the
  /// views of the last seconds are the ones the craft still sees. With 5 s, a HIL restart in the
  /// hover found only the take-off's keyframes (the climb's were newer than the checkpoint) and
  /// stayed lost for 33 frames, past quad-control's 2 s lost-hold: it landed. A map that does not
  /// change (steady hover, revisits) is not rewritten; what a write costs is in docs/slam.md.
  double checkpoint_period_s = 1.0;
  bool is_valid(std::string* error) const;
};

/// Everything known about one frame once the pipeline is finished.
struct FrameRecord {
  std::int64_t index = 0;
  double stamp_s = 0;
  bool ok = false;  ///< false: the front-end rejected the frame (see error)
  std::string error;
  TrackingState state = TrackingState::kInitialising;
  bool backend_processed = false;
  bool keyframe = false;
  bool llc_applied = false;
  bool loop_closed = false;
  bool relocalised =
      false;  ///< local-map system: the pose came from the keyframe database (TrackResult)
  bool cross_checked = false;  ///< local-map system: a weak fit was cross-checked (TrackResult)
  double cross_check_shift_m = -1, cross_check_shift_deg = -1;  ///< (TrackResult)
  bool prediction_stale =
      false;  ///< local-map system: the gap exceeded the tracker's max_predicted_gap_s
  bool attitude_predicted = false;  ///< local-map system: rotation predicted from the IMU attitude
  double prediction_deviation_m = -1,
         prediction_deviation_bound_m = -1;  ///< local-map system (TrackResult)
  std::int64_t reference_keyframe = -1;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< as estimated online
  Eigen::Isometry3d T_prev_cur = Eigen::Isometry3d::Identity();   ///< front-end egomotion
  Eigen::Isometry3d T_kf_cam = Eigen::Isometry3d::Identity();
  std::size_t features = 0, matches = 0, inliers = 0;
  /// Local-map system: matching_ms = local map + projection search with its pose optimisations,
  /// ransac_ms = relocalisation (TrackResult).
  double features_ms = 0, matching_ms = 0, ransac_ms = 0, frontend_ms = 0;
  double keyframe_ms = 0, llc_ms = 0, glc_ms = 0, posegraph_ms = 0, backend_ms = 0;
  double frontend_cpu_ms = 0, backend_cpu_ms = 0;
  std::size_t map_keyframes = 0, map_points = 0;  ///< local-map system: map size after this frame
  /// Local-map system: the keyframe rule's verdict and inputs (TrackResult).
  KeyframeReason keyframe_wanted = KeyframeReason::kNone;
  int ref_tracked = 0, near_tracked = 0, near_untracked = 0;
  double near_redundant = -1;
  double map_lock_wait_ms =
      0;  ///< local-map system: the tracker's wait for the map lock (TrackResult)
  /// Map corrections T_world_cam is expressed after: loop corrections of the local map
  /// (TrackResult), or loop closures the VO back-end had applied when this pose was given. A change
  /// from one frame to the next declares a jump of the world frame (PoseUpdate.map_correction_count
  /// on the wire).
  std::uint64_t map_corrections = 0;
};

struct PipelineSummary {
  std::size_t frames_submitted = 0;
  std::size_t frontend_dropped =
      0;  ///< real-time mode: frames replaced before the front-end took them
  std::size_t backend_skipped = 0;  ///< real-time mode: front-end outputs the back-end never saw
  std::size_t frames_failed = 0;
  std::size_t keyframes = 0;
  std::size_t loop_closures = 0;
  std::size_t optimisations = 0;
  // Local-map system only:
  std::size_t map_points = 0;
  std::size_t keyframes_culled = 0;
  std::size_t relocalisations = 0;  ///< frames whose pose came from the keyframe database
                                    ///< after a loss or a stale prediction
  /// Weak fits cross-checked against the reference keyframe, and those whose pose it replaced.
  std::size_t cross_checks = 0, cross_check_replacements = 0;
  std::size_t frames_lost = 0;
  bool loop_closing_active =
      false;  ///< the loop closer ran (option on and a vocabulary for the detector)
  std::size_t loop_detections = 0;  ///< keyframes with database candidates passed to verification
  std::string
      tracking_thread;  ///< the tracking thread's scheduling, when PipelineOptions asked for one
  std::string mapping_thread;  ///< the local-mapping thread's scheduling (realtime/live modes)
  std::size_t mapper_caught_up = 0;  ///< keyframes whose fusion/BA was left to a newer keyframe
  std::size_t mapper_ba_interrupted = 0;  ///< local BAs stopped early by a waiting keyframe
  /// Map checkpoints (PipelineOptions::checkpoint_path): written, the slowest copy + write (ms),
  /// and the last failure ("" when none).
  std::size_t checkpoints_written = 0;
  double checkpoint_max_ms = 0;
  std::string checkpoint_error;
};

/// Keyframes in the mapper (queued + in work) below which the tracker makes keyframes as it needs
/// them (realtime/live).
inline constexpr std::size_t kMaxQueuedKeyframes = 2;
/// Beyond kMaxQueuedKeyframes, weak tracking still adds keyframes up to this many in the mapper
/// (ORB-SLAM2's RGB-D rule: insert while fewer than 3 wait). The tracker creates a keyframe's
/// points from its depth itself, so the keyframe helps tracking at once, and the mapper, seeing
/// it wait, leaves its own work to it (LocalMapper catch-up). Without it a starved mapper kept the
/// tracker from adding keyframes for 11 frames of a fresh-clone HIL flight: inliers 290 -> 32,
/// lost.
inline constexpr std::size_t kMaxQueuedKeyframesWeak = 3;

/// What the tracker may do about keyframes while `keyframes_in_mapper` (queued + in work) wait.
struct KeyframeAdmission {
  bool allowed = true;      ///< a keyframe may be made (Tracker::track's keyframe_allowed)
  bool mapper_idle = true;  ///< false: only weak tracking makes one (Tracker::track's mapper_idle)
};
/// `gate_on_busy_mapper`: PipelineOptions::keyframe_gate_mapper_busy.
KeyframeAdmission keyframe_admission(std::size_t keyframes_in_mapper, bool gate_on_busy_mapper);

struct MapFileContext;  // slam/localmap/map_io.hpp

class Pipeline {
 public:
  static std::unique_ptr<Pipeline> create(const PipelineOptions& options,
                                          const Intrinsics& intrinsics, std::string* error);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Hands over the next frame (see the modes above). Returns false after finish().
  bool submit(RgbdFrame frame);
  /// Drains both stages and joins the threads. Idempotent.
  void finish();

  /// Where a record goes when it is retired (see retire_records).
  using RecordSink = std::function<void(const FrameRecord&)>;
  /// Keeps only the newest `retained` (>= 1) records; older ones are handed to `sink` (empty:
  /// dropped) on the thread that made the newer record, outside the pipeline's locks. For a
  /// service that runs for a whole flight (slam-server): its memory does not grow per frame. Call
  /// before the first frame; by default every record is kept (slam-eval: ATE and tables).
  /// A record is retired as made: keep `retained` above the frames a back-end may still update.
  void retire_records(std::size_t retained, RecordSink sink);

  /// Valid after finish(): records in index order (the retained ones, see retire_records), and the
  /// final trajectory where each frame is re-anchored to the optimised pose of its reference
  /// keyframe.
  std::vector<FrameRecord> records() const;
  std::vector<std::pair<double, Eigen::Isometry3d>> final_trajectory() const;
  PipelineSummary summary() const;
  /// Record of frame `index` as it stands now (sequential mode: final once submit() returned).
  std::optional<FrameRecord> record(std::int64_t index) const;
  const BackEnd& backend() const { return *backend_; }
  /// Local-map system: the map (lock `mutex` to read while running), and per-keyframe mapping
  /// stats.
  std::shared_ptr<SharedMap> local_map() const { return map_; }
  std::vector<MapperStats> mapper_stats() const;
  std::vector<LoopStats> loop_stats() const;
  /// Local-map system: starts from the map in `path` (before the first frame; the first frames
  /// relocalise in it, poses are in its world frame, map corrections counted on from the file's).
  /// False with `error`: wrong version, camera, detector, corrupt file, or frames already
  /// submitted.
  bool load_map(const std::string& path, std::string* error);
  /// Local-map system: writes the current map (call after finish() for the final one).
  bool save_map(const std::string& path, std::string* error) const;
  bool is_local_map() const { return options_.backend.kind == BackendKind::kLocalMap; }

 private:
  Pipeline(PipelineOptions options, FrontEnd frontend, BackEnd backend);
  void frontend_loop();
  void backend_loop();
  void run_frontend(const RgbdFrame& frame);
  void run_backend(const FrontendOutput& out);
  void run_tracker(const RgbdFrame& frame);
  /// Appends a record (caller holds mutex_), retiring the oldest beyond retained_records_.
  void push_record_locked(FrameRecord rec);
  /// Hands the retired records to the sink (caller does not hold mutex_).
  void hand_retired();
  void mapper_loop();
  /// kRealtime or kLive: frames are paced by the camera and never wait for mapping.
  bool paced() const {
    return options_.mode == PipelineMode::kRealtime || options_.mode == PipelineMode::kLive;
  }
  /// Schedules the calling (mapping) thread: real-time below tracking when tracking is real-time.
  ThreadPriorityResult place_mapping_thread() const;
  void loop_closing_loop();
  /// Loop-closes keyframe `kf` and records its stats (the loop thread, or inline in sequential
  /// mode).
  void close_loops(std::int64_t kf);
  /// Writes the map checkpoint (PipelineOptions::checkpoint_path) when due, or always if `force`.
  /// Called by the thread that finished a keyframe, and by finish().
  void checkpoint_if_due(bool force);
  /// The camera and detector a map file of this pipeline must match (save, load, checkpoints).
  MapFileContext map_file_context() const;

  PipelineOptions options_;
  std::optional<FrontEnd> frontend_;
  std::optional<BackEnd> backend_;

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<RgbdFrame> input_;          // capacity 1
  std::deque<FrontendOutput> handover_;  // capacity 1
  bool input_closed_ = false;
  bool handover_closed_ = false;
  std::atomic<bool> finished_{false};
  std::deque<FrameRecord> records_;
  std::size_t retained_records_ = 0;  ///< 0: all (retire_records)
  RecordSink record_sink_;
  std::vector<FrameRecord> retired_;  ///< retired under mutex_, handed to record_sink_ outside it
  // Latest back-end correction C = T_world_cam * T_odom_cam^-1 (used for skipped frames).
  Eigen::Isometry3d correction_ = Eigen::Isometry3d::Identity();
  std::uint64_t backend_loop_corrections_ = 0;  // loop closures folded into correction_
  PipelineSummary summary_;
  // Local-map system (BackendKind::kLocalMap).
  std::optional<FeatureExtractor> extractor_;
  CameraModel camera_;
  std::shared_ptr<SharedMap> map_;
  std::optional<Tracker> tracker_;
  std::optional<LocalMapper> mapper_;
  std::deque<std::int64_t> keyframe_queue_;
  bool mapper_busy_ = false;
  bool keyframes_closed_ = false;
  std::vector<MapperStats> mapper_stats_;
  std::optional<LoopCloser> loop_closer_;
  std::deque<std::int64_t>
      loop_queue_;  // mapped keyframes waiting for loop closing (one per keyframe)
  bool loop_busy_ = false;
  bool loop_closed_ = false;
  std::vector<LoopStats> loop_stats_;
  // Map checkpoints: the newest keyframe's stamp and the map's corrections at the last one.
  std::mutex checkpoint_mutex_;  // one writer at a time (mapping and loop threads, finish)
  std::optional<double> checkpoint_stamp_s_;
  std::uint64_t checkpoint_corrections_ = 0;
  std::thread frontend_thread_;
  std::thread backend_thread_;
  std::thread loop_thread_;
};

}  // namespace slam
