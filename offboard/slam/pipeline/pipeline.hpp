// The SLAM pipeline: a facade that builds one SLAM system from the options and feeds it frames.
//   - BackendKind::kLocalMap: the flying system (LocalMapSystem: tracking, local mapping and loop
//     closing, each on its own thread);
//   - kVo / kLlc / kGlc: the thesis systems (ThesisSystem: front-end and back-end threads).
// How frames are paced (PipelineMode) is described with each system. Threads live only in the
// systems; every stage they run is a plain class with a process() call.
//
// Thread safety: submit()/finish() from one producer thread; results after finish() (record()
// and summary() at any time).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam/pipeline/frame_record.hpp"
#include "slam/pipeline/frame_records.hpp"
#include "slam/pipeline/local_map_system.hpp"
#include "slam/pipeline/pipeline_options.hpp"
#include "slam/thesis/thesis_system.hpp"

namespace rgbdquad::slam {

class Pipeline {
 public:
  static std::unique_ptr<Pipeline> create(const PipelineOptions& options,
                                          const Intrinsics& intrinsics, std::string* error);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Hands over the next frame (see the modes). Returns false after finish().
  bool submit(RgbdFrame frame);
  /// Drains every stage and joins the threads. Idempotent.
  void finish();

  /// Where a record goes when it is retired (see retire_records).
  using RecordSink = FrameRecords::Sink;
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
  /// Thesis systems: the back-end (its keyframes and pose graph), after finish(); null for the
  /// local-map system.
  const BackEnd* backend() const { return thesis_ ? &thesis_->backend() : nullptr; }
  /// Local-map system: the map (lock `mutex` to read while running), and per-keyframe mapping
  /// and loop-closing stats (empty for the thesis systems).
  std::shared_ptr<SharedMap> local_map() const { return local_ ? local_->map() : nullptr; }
  std::vector<MapperStats> mapper_stats() const;
  std::vector<LoopStats> loop_stats() const;
  /// Local-map system: starts from the map in `path` (before the first frame; the first frames
  /// relocalise in it, poses are in its world frame, map corrections counted on from the file's).
  /// False with `error`: wrong version, camera, detector, corrupt file, or frames already
  /// submitted.
  bool load_map(const std::string& path, std::string* error);
  /// Local-map system: writes the current map (call after finish() for the final one).
  bool save_map(const std::string& path, std::string* error) const;
  bool is_local_map() const { return local_ != nullptr; }

 private:
  Pipeline() = default;
  FrameRecords records_;  // declared first: the systems write to it until they are destroyed
  std::unique_ptr<LocalMapSystem> local_;
  std::unique_ptr<ThesisSystem> thesis_;
  SlamSystem* system_ = nullptr;  // whichever of the two exists
  std::atomic<std::size_t> frames_submitted_{0};
  std::atomic<bool> finished_{false};
};

}  // namespace rgbdquad::slam
