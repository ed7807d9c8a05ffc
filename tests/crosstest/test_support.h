// Helpers shared by the receiver's end-to-end tests: real TUM frames, a scripted frame source,
// bounded waiting, descriptor/memory probes.
#pragma once

#include <dirent.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/frame_source.h"
#include "rgbdquad/capture/tum_replay_source.h"

namespace rgbdquad::testing {

// Waits (sleeping 1 ms between checks) until pred() or timeout; returns pred()'s last value.
inline bool eventually(const std::function<bool()>& pred, int timeout_ms = 5000) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return pred();
}

inline int open_fd_count() {
  int count = 0;
  if (DIR* d = opendir("/proc/self/fd")) {
    while (readdir(d) != nullptr) ++count;
    closedir(d);
  }
  return count;
}

inline long rss_kb() {
  std::ifstream status("/proc/self/status");
  std::string key;
  long value = 0;
  while (status >> key) {
    if (key == "VmRSS:") {
      status >> value;
      return value;
    }
  }
  return 0;
}

// Every frame of a TUM excerpt, decoded once (unpaced replay).
inline std::vector<capture::SourceFrame> load_tum(const std::string& dir) {
  capture::ManualClock clock;
  capture::TumReplayOptions options;
  options.directory = dir;
  options.fps = -1;
  capture::TumReplaySource source(options, &clock);
  std::vector<capture::SourceFrame> frames;
  while (auto f = source.next()) frames.push_back(std::move(*f));
  return frames;
}

// Replays a fixed list of frames once.
class ScriptedSource final : public capture::FrameSource {
 public:
  explicit ScriptedSource(std::vector<capture::SourceFrame> frames) : frames_(std::move(frames)) {}
  std::optional<capture::SourceFrame> next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    return frames_[next_++];
  }
  void stop() override { next_ = frames_.size(); }
  std::string error() const override { return {}; }
  std::string describe() const override { return "scripted"; }

 private:
  std::vector<capture::SourceFrame> frames_;
  std::size_t next_ = 0;
};

inline std::function<std::int64_t()> steady_now_us() {
  return [] {
    return std::chrono::duration_cast<std::chrono::microseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
}

}  // namespace rgbdquad::testing
