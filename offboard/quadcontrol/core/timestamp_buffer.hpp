// A bounded, time-ordered buffer that answers "which sample is nearest to time t?": how IMU
// replies of the firmware are matched to camera frames (thesis: replies are saved with a
// timestamp to match frames). Times in microseconds on one clock, passed in.
// Not thread-safe: the owner guards it.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <deque>
#include <optional>
#include <utility>

namespace rgbdquad::quadcontrol {

template <typename T>
class TimestampBuffer {
 public:
  explicit TimestampBuffer(std::size_t capacity) : capacity_(capacity == 0 ? 1 : capacity) {}

  /// Appends a sample; samples older than the newest one are dropped (time must not go back).
  bool push(std::int64_t t_us, T value) {
    if (!samples_.empty() && t_us < samples_.back().first) return false;
    samples_.emplace_back(t_us, std::move(value));
    while (samples_.size() > capacity_) samples_.pop_front();
    return true;
  }

  /// The sample nearest to t_us if within max_dt_us (ties: the earlier one).
  std::optional<std::pair<std::int64_t, T>> nearest(std::int64_t t_us,
                                                    std::int64_t max_dt_us) const {
    std::optional<std::pair<std::int64_t, T>> best;
    std::int64_t best_dt = 0;
    for (const auto& s : samples_) {
      const std::int64_t dt = std::llabs(s.first - t_us);
      if (dt <= max_dt_us && (!best || dt < best_dt)) {
        best = s;
        best_dt = dt;
      }
    }
    return best;
  }

  std::size_t size() const { return samples_.size(); }

 private:
  std::size_t capacity_;
  std::deque<std::pair<std::int64_t, T>> samples_;
};

}  // namespace rgbdquad::quadcontrol
