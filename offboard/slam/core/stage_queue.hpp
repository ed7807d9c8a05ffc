// A bounded hand-over queue between two SLAM threads, with the two policies the pipeline needs:
// newest-wins (a paced producer never blocks; what waited is replaced and counted) and
// wait-for-room (every item goes through, in order). The consumer marks the item it took as in
// work until it calls done(), so "idle" means nothing queued and nothing being processed.
//
// Thread safety: any number of producers and consumers; every member locks the queue's own mutex.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

namespace rgbdquad::slam {

template <typename T>
class StageQueue {
 public:
  /// `capacity` >= 1 bounds push_waiting() and push_replacing(); push() does not look at it (its
  /// caller bounds the queue, e.g. keyframe admission).
  explicit StageQueue(std::size_t capacity) : capacity_(capacity < 1 ? 1 : capacity) {}

  /// Appends `item`, first dropping what waits beyond capacity - 1 (newest wins). Never blocks.
  /// Returns how many waiting items were dropped.
  std::size_t push_replacing(T item) {
    std::size_t dropped = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      while (items_.size() >= capacity_) {
        items_.pop_front();
        ++dropped;
      }
      items_.push_back(std::move(item));
    }
    changed_.notify_all();
    return dropped;
  }

  /// Appends `item` once the queue has room (blocks while full).
  void push_waiting(T item) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return items_.size() < capacity_; });
      items_.push_back(std::move(item));
    }
    changed_.notify_all();
  }

  /// Appends `item` whatever the queue holds.
  void push(T item) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      items_.push_back(std::move(item));
    }
    changed_.notify_all();
  }

  /// Blocks until an item is queued (returned and marked in work until done()) or the queue is
  /// closed and empty (nullopt: the consumer ends).
  std::optional<T> pop() {
    std::optional<T> item;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return !items_.empty() || closed_; });
      if (items_.empty()) return std::nullopt;
      item = std::move(items_.front());
      items_.pop_front();
      ++in_work_;
    }
    changed_.notify_all();
    return item;
  }

  /// The item taken by pop() is finished.
  void done() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (in_work_ > 0) --in_work_;
    }
    changed_.notify_all();
  }

  /// No more items: pop() returns nullopt once the queue is empty.
  void close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    changed_.notify_all();
  }

  /// Items queued plus items in work.
  std::size_t load() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size() + in_work_;
  }
  bool has_waiting() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return !items_.empty();
  }
  /// Blocks until nothing is queued and nothing is in work.
  void wait_idle() const {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return items_.empty() && in_work_ == 0; });
  }

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::deque<T> items_;
  std::size_t in_work_ = 0;
  bool closed_ = false;
};

/// Runs `process` on every item of `queue` until it is closed and drained (a stage thread's body).
template <typename T, typename Process>
void drain_stage_queue(StageQueue<T>& queue, Process&& process) {
  while (std::optional<T> item = queue.pop()) {
    process(std::move(*item));
    queue.done();
  }
}

}  // namespace rgbdquad::slam
