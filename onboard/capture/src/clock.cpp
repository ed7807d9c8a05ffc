// Real monotonic clock.
#include "rgbdquad/capture/clock.h"

#include <chrono>
#include <thread>

namespace rgbdquad::capture {

std::int64_t SteadyClock::now_us() const {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void SteadyClock::sleep_until_us(std::int64_t deadline_us) {
  std::this_thread::sleep_until(
      std::chrono::steady_clock::time_point(std::chrono::microseconds(deadline_us)));
}

}  // namespace rgbdquad::capture
