// The flying SLAM system: three stages at three rates, each owning its thread and its input queue
// (ORB-SLAM3's split) - tracking per frame (the camera-to-command path), local mapping per
// keyframe, loop closing per mapped keyframe - around one shared map; with map checkpoints, a
// fourth thread writes them (CheckpointStage). Each stage's process() is a
// plain call, testable without threads; the stage runs it on its own thread or, in sequential
// mode, inline on the caller's.
//
// Pacing (PipelineMode):
//  - kSequential: every stage runs inline in submit();
//  - kWait: tracking thread; after each keyframe it waits until mapping and loop closing have
//    finished it (deterministic, equal to kSequential);
//  - kRealtime: tracking thread fed newest-frame-wins; keyframes queue for mapping (bounded by
//    keyframe_admission), tracking never waits for mapping;
//  - kLive: tracking inline on the caller's thread (the pose is final when submit() returns),
//    mapping and loop closing on their threads.
//
// Thread safety: submit()/finish() from one producer thread; results from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "slam/core/stage_queue.hpp"
#include "slam/features/features.hpp"
#include "slam/loopclosing/loop_closer.hpp"
#include "slam/mapping/local_mapper.hpp"
#include "slam/pipeline/frame_records.hpp"
#include "slam/pipeline/map_checkpointer.hpp"
#include "slam/pipeline/pipeline_options.hpp"
#include "slam/pipeline/slam_system.hpp"
#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

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

/// Beyond kMaxQueuedKeyframesWeak, a frame that would otherwise be lost still starts a map segment
/// up to this many in the mapper. A segment's first keyframe carries its own points, so tracking
/// goes on in it before the mapper reaches it. Two back-to-back segment starts on a fast turn had
/// filled kMaxQueuedKeyframesWeak, and the third failing frame was lost (fr1_360 in real time);
/// two more slots keep the mapper's backlog, and so its latency, bounded.
inline constexpr std::size_t kMaxQueuedKeyframesSegmentStart = kMaxQueuedKeyframesWeak + 2;

/// What the tracker may do about keyframes while `keyframes_in_mapper` (queued + in work) wait.
/// `gate_on_busy_mapper`: PipelineOptions::keyframe_gate_mapper_busy.
KeyframeAdmission keyframe_admission(std::size_t keyframes_in_mapper, bool gate_on_busy_mapper);

/// How a stage's thread is paced and scheduled (from PipelineOptions).
struct StagePacing {
  PipelineMode mode = PipelineMode::kWait;
  ThreadPolicy tracking_thread_policy = ThreadPolicy::kOff;
  int mapping_rt_priority = 5;
  /// Records or replays the timing-dependent answers (keyframe admission, catch-up) with the
  /// map-lock order; null: off.
  std::shared_ptr<LockSchedule> schedule;
  /// kRealtime or kLive: frames are paced by the camera and never wait for mapping.
  bool paced() const { return mode == PipelineMode::kRealtime || mode == PipelineMode::kLive; }
};

/// Loop closing of each mapped keyframe (LoopCloser), on the "slam-loop" thread.
class LoopClosingStage {
 public:
  /// `after_keyframe`: called on the stage's thread once a keyframe is loop-closed (checkpoints).
  LoopClosingStage(LoopCloser closer, StagePacing pacing, std::function<void()> after_keyframe);
  ~LoopClosingStage() { finish(); }
  LoopClosingStage(const LoopClosingStage&) = delete;
  LoopClosingStage& operator=(const LoopClosingStage&) = delete;

  void start();
  /// Queues keyframe `kf` (sequential mode: closes it inline).
  void submit(std::int64_t kf);
  /// Loop-closes keyframe `kf`; nothing escapes (the map stays as mapped).
  LoopStats process(std::int64_t kf);
  void wait_idle() const { queue_.wait_idle(); }
  void finish();
  std::vector<LoopStats> stats() const;
  LoopCloser& closer() { return closer_; }

 private:
  void run();
  void close(std::int64_t kf);
  LoopCloser closer_;
  const StagePacing pacing_;
  std::function<void()> after_keyframe_;
  StageQueue<std::int64_t> queue_{1};  // unbounded push(): one per mapped keyframe
  mutable std::mutex stats_mutex_;
  std::vector<LoopStats> stats_;
  std::thread thread_;
};

/// Map checkpoints (MapCheckpointer), written on the "slam-checkpoint" thread so that neither
/// tracking nor mapping waits for a file: a checkpoint falls due after a mapped keyframe or, with
/// the map changed and no keyframe since, at a later frame (MapCheckpointer says when).
class CheckpointStage {
 public:
  /// `checkpointer` outlives the stage.
  CheckpointStage(MapCheckpointer* checkpointer, StagePacing pacing);
  ~CheckpointStage() { finish(); }
  CheckpointStage(const CheckpointStage&) = delete;
  CheckpointStage& operator=(const CheckpointStage&) = delete;

  void start();
  /// Has the claimed checkpoint written at data time `now_s` (sequential mode: inline). Never
  /// blocks otherwise.
  void request(double now_s);
  void finish();

 private:
  MapCheckpointer* checkpointer_;
  const StagePacing pacing_;
  StageQueue<double> queue_{1};  // newest wins: a write covers every change before its copy
  std::thread thread_;
};

/// Local mapping of each keyframe (LocalMapper), on the "slam-mapping" thread.
class LocalMappingStage {
 public:
  /// `after_keyframe(kf)`: called on the stage's thread once keyframe `kf` is mapped (hands it to
  /// loop closing, or writes a checkpoint), before the stage reports idle.
  LocalMappingStage(LocalMapper mapper, StagePacing pacing,
                    std::function<void(std::int64_t)> after_keyframe);
  ~LocalMappingStage() { finish(); }
  LocalMappingStage(const LocalMappingStage&) = delete;
  LocalMappingStage& operator=(const LocalMappingStage&) = delete;

  void start();
  /// Queues keyframe `kf` (sequential mode: maps it inline).
  void submit(std::int64_t kf);
  /// Maps keyframe `kf`; `waiting` lets the BA yield to a newer keyframe. Nothing escapes.
  MapperStats process(std::int64_t kf, const LocalMapper::KeyframesWaiting& waiting);
  /// Keyframes queued plus in work.
  std::size_t load() const { return queue_.load(); }
  void wait_idle() const { queue_.wait_idle(); }
  void finish();
  std::vector<MapperStats> stats() const;
  /// mapping_thread, mapper_caught_up, mapper_ba_interrupted.
  void add_to(PipelineSummary* summary) const;

 private:
  void run();
  void map(std::int64_t kf, const LocalMapper::KeyframesWaiting& waiting);
  /// Schedules the calling (mapping) thread: real-time below tracking when tracking is real-time.
  ThreadPriorityResult place_thread() const;
  LocalMapper mapper_;
  const StagePacing pacing_;
  std::function<void(std::int64_t)> after_keyframe_;
  StageQueue<std::int64_t> queue_{1};  // unbounded push(): keyframe_admission bounds it
  mutable std::mutex stats_mutex_;
  std::vector<MapperStats> stats_;
  std::string thread_description_;
  std::size_t caught_up_ = 0, ba_interrupted_ = 0;
  std::thread thread_;
};

/// Per-frame tracking (features + Tracker), on the "slam-tracking" thread (kWait, kRealtime) or
/// the caller's (kSequential, kLive).
class TrackingStage {
 public:
  /// One tracked frame: its record and, when it became one, the keyframe for mapping.
  struct Output {
    FrameRecord record;
    std::optional<std::int64_t> keyframe;
  };
  /// `admission`: what the mapper can take now (paced modes); `records`: where each frame's
  /// record goes; `on_keyframe(kf)`: hands a new keyframe on (and, in kWait, waits for it).
  TrackingStage(FeatureExtractor extractor, Tracker tracker, StagePacing pacing,
                std::function<KeyframeAdmission()> admission, FrameRecords* records,
                std::function<void(std::int64_t)> on_keyframe, const Intrinsics& intrinsics,
                bool align_depth_time, double colour_stamp_lag_s);
  ~TrackingStage() { finish(); }
  TrackingStage(const TrackingStage&) = delete;
  TrackingStage& operator=(const TrackingStage&) = delete;

  void start();
  /// Hands over the next frame as the mode says (see the file comment).
  void submit(RgbdFrame frame);
  /// Extracts features and tracks `frame`. Nothing escapes: a failure is in the record.
  Output process(const RgbdFrame& frame, KeyframeAdmission admission);
  void finish();
  /// frontend_dropped, tracking_thread, relocalisations, cross-checks, frames_lost.
  void add_to(PipelineSummary* summary) const;
  Tracker& tracker() { return tracker_; }

 private:
  void run();
  void track(const RgbdFrame& frame);
  /// The frame with its depth re-timed to the colour image (TrackerOptions::align_depth_time).
  RgbdFrame depth_aligned(const RgbdFrame& frame) const;
  FeatureExtractor extractor_;
  Tracker tracker_;
  const Intrinsics intrinsics_;
  const bool align_depth_time_;
  const double colour_stamp_lag_s_;
  const StagePacing pacing_;
  std::function<KeyframeAdmission()> admission_;
  FrameRecords* records_;
  std::function<void(std::int64_t)> on_keyframe_;
  StageQueue<RgbdFrame> queue_{1};  // one frame: newest wins (kRealtime) or waits (kWait)
  mutable std::mutex counts_mutex_;
  PipelineSummary counts_;  // only the fields add_to() names
  std::thread thread_;
};

class LocalMapSystem : public SlamSystem {
 public:
  /// `options.backend.kind` must be kLocalMap; `records` outlives the system.
  static std::unique_ptr<LocalMapSystem> create(const PipelineOptions& options,
                                                const Intrinsics& intrinsics, FrameRecords* records,
                                                std::string* error);
  ~LocalMapSystem() override;

  void submit(RgbdFrame frame) override;
  void finish() override;
  PipelineSummary summary() const override;
  std::vector<std::pair<double, Eigen::Isometry3d>> final_trajectory() const override;

  std::shared_ptr<SharedMap> map() const { return map_; }
  std::vector<MapperStats> mapper_stats() const { return mapping_->stats(); }
  std::vector<LoopStats> loop_stats() const;
  /// Starts from the map in `path` (before the first frame); see Pipeline::load_map.
  bool load_map(const std::string& path, std::string* error);
  bool save_map(const std::string& path, std::string* error) const;

 private:
  LocalMapSystem(const PipelineOptions& options, CameraModel camera, FrameRecords* records);
  /// Tracking's hand-over of keyframe `kf` (in kWait it returns once the keyframe is finished).
  void keyframe_made(std::int64_t kf);
  /// A keyframe finished changing the map (mapping, or loop closing when on): checkpoint pending.
  void map_changed();
  MapFileContext map_file_context() const;
  /// Opens PipelineOptions::lock_schedule_record_path or _replay_path into map_->schedule.
  bool open_lock_schedule(std::string* error);

  const PipelineOptions options_;
  const CameraModel camera_;
  std::atomic<bool> finished_{false};
  FrameRecords* records_;
  std::shared_ptr<SharedMap> map_;
  std::unique_ptr<MapCheckpointer> checkpointer_;
  std::unique_ptr<CheckpointStage> checkpoint_;     // null: no checkpoints
  std::unique_ptr<LoopClosingStage> loop_closing_;  // null: loop closing off
  std::unique_ptr<LocalMappingStage> mapping_;
  std::unique_ptr<TrackingStage> tracking_;
};

}  // namespace rgbdquad::slam
