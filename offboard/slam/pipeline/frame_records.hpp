// The per-frame records of a SLAM run, bounded for services that run for a whole flight.
//
// Thread safety: every member locks the store's own mutex; the sink is called outside it, on the
// thread that added the record that retired the old ones.
#pragma once

#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <vector>

#include "slam/pipeline/frame_record.hpp"

namespace rgbdquad::slam {

class FrameRecords {
 public:
  using Sink = std::function<void(const FrameRecord&)>;

  /// Keeps only the newest `retained` (>= 1) records; older ones go to `sink` (empty: dropped).
  void retire(std::size_t retained, Sink sink);
  /// Appends a record (counting it as failed when !ok) and hands the records it retires to the
  /// sink.
  void add(FrameRecord record);
  /// Orders the held records by frame index (once the run is finished).
  void sort_by_index();
  /// Calls `update` on the newest record of frame `index` (under the lock), if it is still held.
  void update(std::int64_t index, const std::function<void(FrameRecord&)>& update);
  std::optional<FrameRecord> find(std::int64_t index) const;
  /// Held records in index order.
  std::vector<FrameRecord> sorted() const;
  /// Calls `read` on the held records, in the order added, under the lock.
  void read(const std::function<void(const std::deque<FrameRecord>&)>& read) const;
  std::size_t failed() const;

 private:
  mutable std::mutex mutex_;
  std::deque<FrameRecord> records_;
  std::size_t retained_ = 0;  ///< 0: all
  std::size_t failed_ = 0;
  Sink sink_;
};

}  // namespace rgbdquad::slam
