// Drops frames that must never be sent: blank (all-zero depth, all-black RGB - what old Kinect
// drivers deliver now and then), malformed (size or buffer length not the configured one) and
// out-of-order (capture timestamp not increasing per channel). Counts each reason.
//
// Thread safety: one instance per capture thread; counters() returns a copy.
#pragma once

#include <cstdint>
#include <string>

#include "rgbdquad/capture/frame.h"

namespace rgbdquad::capture {

struct FrameValidatorOptions {
  int width_px = kKinectWidthPx;
  int height_px = kKinectHeightPx;
  // An RGB frame whose every byte is <= this level is blank. 0: drivers' blank frames are
  // zero-filled buffers, while a real but dark scene still has sensor noise above 0.
  int rgb_black_level = 0;

  bool is_valid(std::string* error) const;
};

struct ValidationCounters {
  std::uint64_t rgb_ok = 0;
  std::uint64_t depth_ok = 0;
  std::uint64_t rgb_blank = 0;
  std::uint64_t depth_blank = 0;
  std::uint64_t malformed = 0;     // wrong size / buffer length / depth units
  std::uint64_t out_of_order = 0;  // timestamp <= previous of the same channel
  std::uint64_t dropped() const { return rgb_blank + depth_blank + malformed + out_of_order; }
};

enum class Verdict { kOk, kBlank, kMalformed, kOutOfOrder };
const char* to_string(Verdict verdict);

class FrameValidator {
 public:
  explicit FrameValidator(const FrameValidatorOptions& options);
  // Classifies the frame and updates the counters. Only kOk frames may be sent.
  Verdict check(const SourceFrame& frame);
  ValidationCounters counters() const { return counters_; }

 private:
  Verdict check_rgb(const RgbFrame& frame);
  Verdict check_depth(const DepthFrame& frame);

  FrameValidatorOptions options_;
  ValidationCounters counters_;
  std::int64_t last_rgb_us_ = INT64_MIN;
  std::int64_t last_depth_us_ = INT64_MIN;
};

}  // namespace rgbdquad::capture
