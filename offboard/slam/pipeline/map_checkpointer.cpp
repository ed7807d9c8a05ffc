// Map checkpoints; see map_checkpointer.hpp.
#include "slam/pipeline/map_checkpointer.hpp"

#include <algorithm>

namespace rgbdquad::slam {

MapCheckpointer::MapCheckpointer(std::string path, double period_s, std::shared_ptr<SharedMap> map,
                                 MapFileContext context)
    : path_(std::move(path)), period_s_(period_s), map_(std::move(map)), context_(context) {}

void MapCheckpointer::write_if_due(bool force) {
  if (path_.empty()) return;
  std::lock_guard<std::mutex> writer(writer_);
  const std::int64_t t0 = steady_now_ns();
  SlamMap copy;
  std::uint64_t corrections = 0;
  double stamp_s = 0;
  {
    std::lock_guard<MapMutex> lock(map_->mutex);
    if (map_->map.keyframes().empty()) return;
    stamp_s = map_->map.keyframes().rbegin()->second.stamp_s;
    corrections = map_->corrections;
    // A map without new keyframes and without a correction is not rewritten.
    const bool due = !stamp_s_ || (stamp_s > *stamp_s_ && stamp_s - *stamp_s_ >= period_s_) ||
                     corrections != corrections_;
    if (!due && !force) return;
    copy = map_->map;  // keyframe features and descriptors are shared, never written in place
  }
  std::string error;
  const bool ok = slam::save_map(path_, copy, context_, &error, corrections);
  const double ms = ms_since(t0);
  stamp_s_ = stamp_s;
  corrections_ = corrections;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  if (ok) {
    ++stats_.written;
    stats_.max_ms = std::max(stats_.max_ms, ms);
  } else {
    stats_.error = error;
  }
}

CheckpointStats MapCheckpointer::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

}  // namespace rgbdquad::slam
