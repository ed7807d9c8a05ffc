// SLAM-link session (protocol/spec/messages.json, link "slam"): one flight's map, socket-free.
// It answers every RgbdFrame with exactly one PoseUpdate (the spec's rule): the pose computed by
// the SLAM pipeline (live mode: tracked on this thread, so the answer belongs to that very frame;
// mapping on its own thread), or - when the frame cannot be used (unsupported encoding,
// inconsistent sizes, the front end rejected it) or the estimate cannot be put on the wire
// (non-finite, not a rotation) - a LOST update carrying the last good pose, with the reason in
// `error`. The pipeline is created on the first frame from the intrinsics and depth scale the frame
// carries; a later frame with another camera model is answered LOST with both calibrations in the
// reason (the map holds one camera). The SlamHello exchange and the choice of session belong to the
// connection (slam_connection.hpp) and the registry (slam_sessions.hpp): a session outlives a
// connection, so a client that reconnects continues the same map and world frame.
//
// The pipeline sits behind SessionPipeline (the calls a session makes): slam-server uses the real
// Pipeline through live_pipeline_factory() (slam_link_pipeline.cpp); the libFuzzer target
// tests/fuzz/fuzz_slam_connection.cpp uses a scripted fake, so the session and the connection are
// fuzzed without building the SLAM engine.
//
// Not thread-safe: used by slam-server's single loop.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "rgbdquad/protocol/messages.hpp"
#include "slam/motion/accel_gate.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace rgbdquad::slamlink {

/// `T` on the wire: translation in metres, unit quaternion (x, y, z, w) re-normalised and each
/// component clamped to [-1, 1] (a rotation matrix that is orthonormal only to rounding can give
/// |w| = 1 + 2e-16, which the codec's range check refuses). nullopt when `T` is non-finite or its
/// rotation is not one (|q| away from 1 by more than 1e-3 before normalisation) or the translation
/// exceeds the spec's range.
std::optional<rgbdquad::protocol::Pose3> pose_to_wire(const Eigen::Isometry3d& T);

/// The lock schedule's name in a session's tables folder (slam/core/lock_schedule.hpp).
inline constexpr const char* kLockScheduleFile = "lock_schedule.txt";

/// Map files of a session (local-map back-end only): a map to start from (the flight relocalises
/// in it and reports poses in its world frame) and where to save the map when the session ends.
struct SessionMapFiles {
  std::string load_path;
  std::string save_path;
  /// When set: the session's per-frame, per-keyframe and loop tables (frames.csv with each frame's
  /// tracking stages in ms, mapping.csv, loops.csv; slam/report/run_tables.hpp) are written into
  /// this folder (created with the pipeline; frames.csv grows during the flight, the others are
  /// written when the session ends) - what slam-eval writes for a dataset, for a flight - and
  /// the map's lock schedule (kLockScheduleFile), which replays the flight's poses exactly.
  std::string tables_dir;
  /// When set: the map is checkpointed here while the session runs (PipelineOptions::
  /// checkpoint_path), so that a slam-server restarted after a crash continues the same map.
  std::string checkpoint_path;
  /// The session continues the map in `checkpoint_path` (its client was told its session
  /// resumed): the first frame loads it and relocalises in its world frame. If it cannot be loaded
  /// (another camera, a file broken since it was checked) every frame is answered LOST with the
  /// reason - a new map here would move the world frame under a client told it was kept.
  bool resume_from_checkpoint = false;
};

/// What a session asks of the SLAM pipeline (the subset of Pipeline it uses, same contracts).
class SessionPipeline {
 public:
  virtual ~SessionPipeline() = default;
  /// Tracks `frame` (kLive: its record is final when this returns). May throw on a bad frame.
  virtual void submit(slam::RgbdFrame frame) = 0;
  virtual std::optional<slam::FrameRecord> record(std::int64_t index) const = 0;
  virtual bool load_map(const std::string& path, std::string* error) = 0;
  virtual bool save_map(const std::string& path, std::string* error) const = 0;
  /// Drains and joins the pipeline's threads. Idempotent.
  virtual void finish() = 0;
  virtual slam::PipelineSummary summary() const = 0;
  /// Before the first frame: starts the run tables in `dir` (exists). frames.csv then grows row by
  /// row as the pipeline retires records, so that a flight's memory does not grow per frame.
  /// False with `error` when the table cannot be created.
  virtual bool start_tables(const std::string& dir, std::string* error) = 0;
  /// After finish(): appends the records still held and writes mapping.csv and loops.csv. False
  /// with `error` on failure (or when start_tables was not called or failed).
  virtual bool finish_tables(std::string* error) = 0;
};

/// Starts a pipeline for the camera a client's first frame describes; null with `error` when the
/// options or the intrinsics are refused.
using PipelineFactory = std::function<std::unique_ptr<SessionPipeline>(
    const slam::PipelineOptions& options, const slam::Intrinsics& intrinsics, std::string* error)>;

/// The real SLAM pipeline (Pipeline::create) behind SessionPipeline.
PipelineFactory live_pipeline_factory();

class SlamLinkSession {
 public:
  /// `options.mode` is forced to kLive (one reply per frame, computed on the caller's thread).
  explicit SlamLinkSession(slam::PipelineOptions options, SessionMapFiles map_files = {},
                           PipelineFactory factory = live_pipeline_factory());

  /// Handles one RgbdFrame; always returns its PoseUpdate (see the file comment). `error` is set
  /// (else cleared) when the update is LOST because of a fault rather than the tracking itself,
  /// or when the pose as computed had to be re-normalised to pass the codec's checks (counted).
  rgbdquad::protocol::PoseUpdate on_frame(const rgbdquad::protocol::RgbdFrame& frame,
                                          std::string* error);

  std::size_t frames_processed() const { return frames_; }
  /// Frames answered LOST because of a fault (bad frame, pipeline error, unencodable pose).
  std::size_t frames_faulted() const { return faulted_; }
  /// Poses the codec refused as computed and that were re-normalised (see pose_to_wire).
  std::size_t poses_repaired() const { return repaired_; }
  /// Accelerometer samples of the frames so far, per gate verdict (used, and ignored per reason).
  const slam::AccelCounts& accel_counts() const { return accel_gate_.counts(); }
  /// The pipeline (null before the first frame); finish() it before reading results.
  SessionPipeline* pipeline() { return pipeline_.get(); }
  /// One line for the log: frames, keyframes, loop closures (finishes the pipeline).
  std::string finish_summary();

 private:
  /// The SLAM frame of a wire frame; its accelerometer sample goes through the session's gate.
  std::optional<slam::RgbdFrame> to_frame(const rgbdquad::protocol::RgbdFrame& m,
                                          std::string* error);
  rgbdquad::protocol::PoseUpdate lost_update(const rgbdquad::protocol::RgbdFrame& frame,
                                             std::string reason, std::string* error);
  /// Builds the pipeline for the first frame's camera `k` and loads the map to resume or load;
  /// "" when the pipeline runs, else why it cannot. A map that cannot be loaded is kept as a
  /// reason (resume_error_, map_load_error_), not returned: the link answers with it.
  std::string start_pipeline(const slam::Intrinsics& k);
  /// The reply for a tracked frame's record: its poses as the wire carries them, or LOST with the
  /// reason when they cannot be sent.
  rgbdquad::protocol::PoseUpdate pose_update(const rgbdquad::protocol::RgbdFrame& frame,
                                             const slam::FrameRecord& rec, std::string* error);

  slam::PipelineOptions options_;
  SessionMapFiles map_files_;
  std::string
      map_load_error_;        ///< why the configured map could not be loaded ("" = loaded or none)
  std::string tables_error_;  ///< why the tables could not be started ("" = started or none)
  std::string resume_error_;  ///< why the checkpoint to resume could not be loaded ("" = loaded)
  PipelineFactory factory_;
  std::unique_ptr<SessionPipeline> pipeline_;
  slam::Intrinsics intrinsics_;  ///< what the pipeline was created with (the session's first frame)
  std::size_t frames_ = 0;
  std::size_t faulted_ = 0;
  std::size_t repaired_ = 0;
  slam::AccelGate
      accel_gate_;  ///< the frames' accelerometer samples, rotated into the camera frame
  rgbdquad::protocol::Pose3 last_good_;  ///< last pose sent while tracking (identity at start)
  std::uint32_t map_corrections_ =
      0;  ///< newest map-correction count sent (LOST answers repeat it)
};

}  // namespace rgbdquad::slamlink
