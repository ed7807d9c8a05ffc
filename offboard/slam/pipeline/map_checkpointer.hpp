// Map checkpoints of the local-map system (PipelineOptions::checkpoint_path): the map, with its
// count of loop corrections, written through a temporary file renamed into place, so that a
// restarted service continues in the same map and world frame.
//
// When: a checkpoint becomes pending when the map changes (map_changed(): a keyframe mapped or
// loop-closed, which is also when keyframes are culled and loops corrected), and is due once
// `period_s` of data time has passed since the last write - at once for the first checkpoint and
// after a loop correction, which moves the whole map. A pending checkpoint is due whether or not
// another keyframe comes: a hovering craft makes no keyframes, and the views it added last are
// the ones a restarted service must relocalise in. Nothing is written while the map does not
// change.
//
// Time is data time (frame and keyframe stamps, seconds), passed in: the period then means the
// same thing in a flight, a replay at any speed and wait mode (where the checkpoints follow the
// data, not the machine's load), and no logic reads a clock. A frame stamp advances with every
// camera frame, so in flight a pending checkpoint is written within one frame of falling due; a
// change made after the last frame of a link that went silent waits for the next frame or for
// the forced write when the map ends.
//
// Thread safety: map_changed() and take_due() may be called from any thread; take_due() is
// lock-free and O(1) (the per-frame check on the camera-to-command path). write() and
// write_forced() from one thread at a time (serialised inside); the map is copied under its lock
// and written outside it.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "slam/map/map_io.hpp"
#include "slam/tracking/tracker.hpp"

namespace rgbdquad::slam {

struct CheckpointStats {
  std::size_t written = 0;
  double max_ms = 0;  ///< slowest copy + write
  std::string error;  ///< the last failure ("" when none)
};

class MapCheckpointer {
 public:
  /// `path` empty: never writes. `period_s` (>= 0): PipelineOptions::checkpoint_period_s.
  MapCheckpointer(std::string path, double period_s, std::shared_ptr<SharedMap> map,
                  MapFileContext context);

  /// The map changed (a keyframe was mapped or loop-closed; keyframes culled and loop corrections
  /// come with one): a checkpoint is pending. Reads the newest keyframe's stamp and the map's
  /// correction count under the map lock. Returns the data time at which the caller should
  /// write() when the checkpoint is due at once (claimed as by take_due()), else nullopt.
  std::optional<double> map_changed();
  /// True once per due checkpoint: a checkpoint is pending and due at data time `now_s`, and no
  /// write of it was claimed yet. The caller then calls write(now_s) (or has it called). Lock-free.
  bool take_due(double now_s);
  /// Writes the checkpoint claimed by take_due()/map_changed() at data time `now_s`.
  void write(double now_s);
  /// Writes the map whatever is pending (when the map ends), if it has keyframes.
  void write_forced();
  /// The data time from which a pending checkpoint is due (-inf: at once), for tests and logs.
  double due_at_s() const { return due_at_s_.load(); }
  bool pending() const { return changes_.load() != written_changes_.load(); }
  CheckpointStats stats() const;

 private:
  /// Copies the map and writes it; `now_s` empty for the forced write.
  void write_map(std::optional<double> now_s);
  /// due_at_s_ from the schedule fields below (schedule_mutex_ held).
  void update_due_at();

  const std::string path_;
  const double period_s_;
  std::shared_ptr<SharedMap> map_;
  const MapFileContext context_;
  std::mutex writer_;  // one write at a time

  // The schedule. changes_ counts map_changed() calls, written_changes_ the count the last
  // written copy includes: pending while they differ (a change during a write stays pending).
  std::atomic<std::uint64_t> changes_{0};
  std::atomic<std::uint64_t> written_changes_{0};
  std::atomic<double> due_at_s_;
  std::atomic<double> last_write_at_s_;  // data time of the last write (-inf: none yet)
  std::atomic<bool> claimed_{false};     // a write of the pending checkpoint is on its way
  std::mutex schedule_mutex_;            // the fields below, and the updates of due_at_s_
  std::optional<double> last_write_s_;
  std::uint64_t seen_corrections_ = 0;
  std::uint64_t written_corrections_ = 0;

  mutable std::mutex stats_mutex_;
  CheckpointStats stats_;
};

}  // namespace rgbdquad::slam
