// Bounded frame records; see frame_records.hpp.
#include "slam/pipeline/frame_records.hpp"

#include <algorithm>

namespace rgbdquad::slam {

void FrameRecords::retire(std::size_t retained, Sink sink) {
  std::lock_guard<std::mutex> lock(mutex_);
  retained_ = std::max<std::size_t>(retained, 1);
  sink_ = std::move(sink);
}

void FrameRecords::add(FrameRecord record) {
  std::vector<FrameRecord> retired;
  Sink sink;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!record.ok) ++failed_;
    records_.push_back(std::move(record));
    while (retained_ > 0 && records_.size() > retained_) {
      retired.push_back(std::move(records_.front()));
      records_.pop_front();
    }
    sink = sink_;
  }
  if (sink)
    for (const FrameRecord& r : retired) sink(r);
}

void FrameRecords::update(std::int64_t index, const std::function<void(FrameRecord&)>& update) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = records_.rbegin(); it != records_.rend(); ++it) {
    if (it->index != index) continue;
    update(*it);
    return;
  }
}

std::optional<FrameRecord> FrameRecords::find(std::int64_t index) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = records_.rbegin(); it != records_.rend(); ++it)
    if (it->index == index) return *it;
  return std::nullopt;
}

void FrameRecords::sort_by_index() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::sort(records_.begin(), records_.end(),
            [](const FrameRecord& a, const FrameRecord& b) { return a.index < b.index; });
}

std::vector<FrameRecord> FrameRecords::sorted() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<FrameRecord> out(records_.begin(), records_.end());
  std::sort(out.begin(), out.end(),
            [](const FrameRecord& a, const FrameRecord& b) { return a.index < b.index; });
  return out;
}

void FrameRecords::read(const std::function<void(const std::deque<FrameRecord>&)>& read) const {
  std::lock_guard<std::mutex> lock(mutex_);
  read(records_);
}

std::size_t FrameRecords::failed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failed_;
}

}  // namespace rgbdquad::slam
