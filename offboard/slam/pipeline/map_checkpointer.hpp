// Map checkpoints of the local-map system (PipelineOptions::checkpoint_path): the map, with its
// count of loop corrections, written through a temporary file renamed into place, so that a
// restarted service continues in the same map and world frame.
//
// Thread safety: write_if_due() may be called from any thread (one writer at a time); the map is
// copied under its lock and written outside it.
#pragma once

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
  /// `path` empty: never writes. `period_s`: PipelineOptions::checkpoint_period_s.
  MapCheckpointer(std::string path, double period_s, std::shared_ptr<SharedMap> map,
                  MapFileContext context);

  /// Writes the checkpoint when due - a keyframe `period_s` of data newer than the last
  /// checkpoint's newest, or a loop correction since - or always if `force` (and the map has
  /// keyframes).
  void write_if_due(bool force);
  CheckpointStats stats() const;

 private:
  const std::string path_;
  const double period_s_;
  std::shared_ptr<SharedMap> map_;
  const MapFileContext context_;
  std::mutex writer_;  // one writer at a time (mapping and loop threads, finish)
  std::optional<double> stamp_s_;
  std::uint64_t corrections_ = 0;
  mutable std::mutex stats_mutex_;
  CheckpointStats stats_;
};

}  // namespace rgbdquad::slam
