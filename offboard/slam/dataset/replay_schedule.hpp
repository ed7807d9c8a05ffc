// When a replayed dataset frame is due and whether it is withheld, for replaying a TUM folder at
// its own rate and simulating a stalled stream (slam-eval --withhold-from/--withhold). Pure: the
// caller reads the clock and sleeps.
#pragma once

#include <chrono>
#include <cstddef>

namespace rgbdquad::slam {

struct ReplaySchedule {
  double period_s = 0;          ///< the dataset's frame period
  double withhold_from_s = -1;  ///< stall start, seconds after the first frame's stamp
  double withhold_s = 0;        ///< stall length (0: none)

  /// Offset from the replay's start at which frame i is due (real-time replay).
  std::chrono::steady_clock::duration due(std::size_t i) const {
    return std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(period_s * static_cast<double>(i)));
  }
  /// True when a frame stamped stamp_s falls into the stall (it never reaches SLAM).
  bool withheld(double stamp_s, double first_stamp_s) const {
    return withhold_s > 0 && stamp_s - first_stamp_s >= withhold_from_s &&
           stamp_s - first_stamp_s < withhold_from_s + withhold_s;
  }
};

}  // namespace rgbdquad::slam
