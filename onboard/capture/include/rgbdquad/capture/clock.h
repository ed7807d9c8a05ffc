// Time as a dependency: components that pace or stamp frames take a Clock, so tests run on a
// simulated clock and only main() wires the real one.
#pragma once

#include <cstdint>

namespace rgbdquad::capture {

class Clock {
 public:
  virtual ~Clock() = default;
  // Monotonic microseconds since an arbitrary epoch.
  virtual std::int64_t now_us() const = 0;
  // Blocks until now_us() >= deadline_us (returns at once if already past).
  virtual void sleep_until_us(std::int64_t deadline_us) = 0;
};

// std::chrono::steady_clock (CLOCK_MONOTONIC). Thread-safe.
class SteadyClock final : public Clock {
 public:
  std::int64_t now_us() const override;
  void sleep_until_us(std::int64_t deadline_us) override;
};

// Simulated clock for tests: sleep_until_us() jumps straight to the deadline. Not thread-safe.
class ManualClock final : public Clock {
 public:
  explicit ManualClock(std::int64_t start_us = 0) : now_us_(start_us) {}
  std::int64_t now_us() const override { return now_us_; }
  void sleep_until_us(std::int64_t deadline_us) override {
    if (deadline_us > now_us_) now_us_ = deadline_us;
  }
  void advance_us(std::int64_t delta_us) { now_us_ += delta_us; }

 private:
  std::int64_t now_us_;
};

}  // namespace rgbdquad::capture
