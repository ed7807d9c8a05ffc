// Rate limit for log lines caused by a peer's input (without it a peer sending garbage gets one
// log line per malformed envelope, i.e. per 16 bytes: a few KiB/s of input becomes MB/s of log). At
// most `burst` lines per `window_us`; the rest are counted and the count is reported with the next
// line let through, or - when no further line comes (the peer went quiet or its connection was
// dropped without a line) - by `take_unreported` once the window is over, so nothing is hidden,
// only summarised. Time is passed in (monotonic microseconds). Not thread-safe: one per serving
// thread.
#pragma once

#include <cstdint>

namespace rgbdquad::receiver {

class LogThrottle {
 public:
  /// Defaults: 5 lines per second, enough to see what a misbehaving streamer sends.
  explicit LogThrottle(int burst = 5, std::int64_t window_us = 1'000'000)
      : burst_(burst), window_us_(window_us) {}

  /// True when a line may be logged at `now_us`; then `*suppressed` is the number of lines
  /// dropped since the last one let through (to be mentioned in that line).
  bool allow(std::int64_t now_us, std::uint64_t* suppressed) {
    if (now_us - window_start_us_ >= window_us_ || now_us < window_start_us_) {
      window_start_us_ = now_us;
      lines_in_window_ = 0;
    }
    if (lines_in_window_ >= burst_) {
      ++suppressed_;
      return false;
    }
    ++lines_in_window_;
    *suppressed = suppressed_;
    suppressed_ = 0;
    return true;
  }

  /// When lines were suppressed and the window they fell in is over at `now_us`: their count
  /// (to be logged on its own); they are then reported; otherwise 0.
  std::uint64_t take_unreported(std::int64_t now_us) {
    if (suppressed_ == 0 || now_us - window_start_us_ < window_us_) return 0;
    const std::uint64_t n = suppressed_;
    suppressed_ = 0;
    return n;
  }

  /// The time at which `take_unreported` will have something to report, or INT64_MAX.
  std::int64_t unreported_due_us() const {
    return suppressed_ == 0 ? INT64_MAX : window_start_us_ + window_us_;
  }

 private:
  int burst_;
  std::int64_t window_us_;
  std::int64_t window_start_us_ = INT64_MIN / 2;
  int lines_in_window_ = 0;
  std::uint64_t suppressed_ = 0;
};

}  // namespace rgbdquad::receiver
