// A bounded, time-ordered buffer that answers "which sample is nearest to time t?": how IMU
// replies of the firmware are matched to camera frames (thesis: replies are saved with a
// timestamp to match frames). Times in microseconds on one clock, passed in.
// Not thread-safe: the owner guards it.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <iterator>
#include <optional>
#include <utility>

#include "rgbdquad/receiver/nearest_stamp.h"

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
    const auto it = receiver::nearest_stamp(samples_.begin(), samples_.end(), t_us,
                                            [](const auto& s) { return s.first; });
    if (it == samples_.end() || std::llabs(it->first - t_us) > max_dt_us) return std::nullopt;
    return *it;
  }

  /// Two neighbouring samples to interpolate t_us between: the newest at or before it and the one
  /// after it; after the newest sample, the newest two (to extrapolate); before the oldest, the
  /// oldest two. nullopt with fewer than two samples.
  std::optional<std::pair<std::pair<std::int64_t, T>, std::pair<std::int64_t, T>>> pair_around(
      std::int64_t t_us) const {
    if (samples_.size() < 2) return std::nullopt;
    auto after = std::upper_bound(samples_.begin(), samples_.end(), t_us,
                                  [](std::int64_t t, const auto& s) { return t < s.first; });
    if (after == samples_.begin()) ++after;
    if (after == samples_.end()) --after;
    return std::make_pair(*std::prev(after), *after);
  }

  std::size_t size() const { return samples_.size(); }

 private:
  std::size_t capacity_;
  std::deque<std::pair<std::int64_t, T>> samples_;
};

}  // namespace rgbdquad::quadcontrol
