// FrameMailbox: the single-slot hand-over between quad-control's frame thread and one SLAM worker
// thread, with the thesis's semantics (Section 3.3.3): the newest frame is handed over, and a frame
// offered while the worker is busy - or while one is already waiting - is dropped and counted.
// Shared by every SlamLink implementation so they differ only in what "process a frame" means.
// Thread-safe: offer()/stats()/note_error()/close() from any thread, take()/finish() from the
// worker.
#pragma once

#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>

#include "app/frame_source.hpp"

namespace rgbdquad::quadcontrol {

struct SlamStats {
  std::size_t submitted = 0, processed = 0, dropped_busy = 0, failed = 0;
  double last_latency_ms = 0.0;
  std::string last_error;
};

class FrameMailbox {
 public:
  /// Offers a frame; false when the worker is busy or a frame is waiting (the frame is dropped).
  bool offer(const CameraFrame& frame) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.submitted;
    if (busy_ || pending_ || closed_) {
      ++stats_.dropped_busy;
      return false;
    }
    pending_ = frame;
    cv_.notify_one();
    return true;
  }

  /// Worker side: waits for a frame and marks the worker busy; nullopt once close() was called.
  std::optional<CameraFrame> take() {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return closed_ || pending_.has_value(); });
    if (closed_) return std::nullopt;
    std::optional<CameraFrame> frame = std::move(pending_);
    pending_.reset();
    busy_ = true;
    return frame;
  }

  /// Worker side: the frame from take() is done; ok = SLAM answered, else error says why.
  void finish(bool ok, double latency_ms, const std::string& error) {
    std::lock_guard<std::mutex> lock(mutex_);
    busy_ = false;
    if (ok) {
      ++stats_.processed;
      stats_.last_latency_ms = latency_ms;
    } else {
      ++stats_.failed;
      stats_.last_error = error;
    }
  }

  /// Records an error that did not end a frame (e.g. bytes dropped by the link decoder).
  void note_error(const std::string& error) {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.last_error = error;
  }

  /// Wakes the worker for good: take() returns nullopt from now on.
  void close() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    cv_.notify_all();
  }

  SlamStats stats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::optional<CameraFrame> pending_;
  bool busy_ = false;
  bool closed_ = false;
  SlamStats stats_;
};

}  // namespace rgbdquad::quadcontrol
