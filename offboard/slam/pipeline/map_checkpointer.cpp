// Map checkpoints; see map_checkpointer.hpp.
#include "slam/pipeline/map_checkpointer.hpp"

#include <algorithm>
#include <limits>

namespace rgbdquad::slam {

namespace {
constexpr double kAtOnce = -std::numeric_limits<double>::infinity();
}  // namespace

MapCheckpointer::MapCheckpointer(std::string path, double period_s, std::shared_ptr<SharedMap> map,
                                 MapFileContext context)
    : path_(std::move(path)),
      period_s_(period_s),
      map_(std::move(map)),
      context_(context),
      due_at_s_(kAtOnce),
      last_write_at_s_(kAtOnce) {}

void MapCheckpointer::update_due_at() {
  const bool at_once = !last_write_s_ || seen_corrections_ != written_corrections_;
  due_at_s_ = at_once ? kAtOnce : *last_write_s_ + period_s_;
  last_write_at_s_ = last_write_s_ ? *last_write_s_ : kAtOnce;
}

std::optional<double> MapCheckpointer::map_changed() {
  if (path_.empty()) return std::nullopt;
  double stamp_s = 0;
  std::uint64_t corrections = 0;
  {
    std::lock_guard<MapMutex> lock(map_->mutex);
    if (map_->map.keyframes().empty()) return std::nullopt;
    stamp_s = map_->map.keyframes().rbegin()->second.stamp_s;
    corrections = map_->corrections;
  }
  {
    std::lock_guard<std::mutex> lock(schedule_mutex_);
    seen_corrections_ = std::max(seen_corrections_, corrections);
    ++changes_;
    update_due_at();
  }
  if (take_due(stamp_s)) return stamp_s;
  return std::nullopt;
}

bool MapCheckpointer::take_due(double now_s) {
  if (changes_.load() == written_changes_.load()) return false;
  // Data time that went back (a client whose clock restarted) must not hold checkpoints off for
  // as long as it takes to catch up: a write is due then.
  if (now_s < due_at_s_.load() && now_s >= last_write_at_s_.load()) return false;
  return !claimed_.exchange(true);
}

void MapCheckpointer::write(double now_s) { write_map(now_s); }

void MapCheckpointer::write_forced() { write_map(std::nullopt); }

void MapCheckpointer::write_map(std::optional<double> now_s) {
  if (path_.empty()) return;
  std::lock_guard<std::mutex> writer(writer_);
  const std::int64_t t0 = steady_now_ns();
  SlamMap copy;
  std::uint64_t corrections = 0;
  std::uint64_t changes = 0;
  bool empty = false;
  {
    std::lock_guard<MapMutex> lock(map_->mutex);
    empty = map_->map.keyframes().empty();
    if (!empty) {
      changes = changes_.load();  // every change made before the copy is in it
      corrections = map_->corrections;
      copy = map_->map;  // keyframe features and descriptors are shared, never written in place
    }
  }
  std::string error;
  const bool ok = !empty && slam::save_map(path_, copy, context_, &error, corrections);
  const double ms = ms_since(t0);
  if (!empty) {
    std::lock_guard<std::mutex> lock(schedule_mutex_);
    // A failed write is retried a period later, not on every frame.
    if (ok) written_changes_ = std::max(written_changes_.load(), changes);
    written_corrections_ = std::max(written_corrections_, corrections);
    if (now_s) last_write_s_ = *now_s;
    update_due_at();
  }
  if (now_s) claimed_ = false;
  if (empty) return;
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
