// The nearest-timestamp search shared by the receiver (pairing RGB with depth) and quad-control
// (matching firmware replies to frames): one definition of "nearest" and of its tie rule.
// Header-only, pure, thread-safe for const ranges.
#pragma once

#include <cstdint>
#include <cstdlib>

namespace rgbdquad::receiver {

/// The element of [first, last) whose stamp (`stamp_us(element)`, microseconds) is nearest to
/// `t_us`; on a tie the one met first wins. `last` when the range is empty.
template <typename Iterator, typename StampUs>
Iterator nearest_stamp(Iterator first, Iterator last, std::int64_t t_us, StampUs stamp_us) {
  Iterator best = last;
  std::int64_t best_dt_us = 0;
  for (Iterator it = first; it != last; ++it) {
    const std::int64_t dt_us = std::llabs(stamp_us(*it) - t_us);
    if (best == last || dt_us < best_dt_us) {
      best = it;
      best_dt_us = dt_us;
    }
  }
  return best;
}

}  // namespace rgbdquad::receiver
