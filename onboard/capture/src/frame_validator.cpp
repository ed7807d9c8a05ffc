// Blank / malformed frame detection.
#include "rgbdquad/capture/frame_validator.h"

#include <algorithm>
#include <cmath>

namespace rgbdquad::capture {

bool FrameValidatorOptions::is_valid(std::string* error) const {
  if (width_px <= 0 || height_px <= 0 || width_px > 4096 || height_px > 4096) {
    *error = "validation image size must be 1..4096 px";
    return false;
  }
  if (rgb_black_level < 0 || rgb_black_level > 254) {
    *error = "rgb_black_level must be 0..254";
    return false;
  }
  return true;
}

const char* to_string(Verdict verdict) {
  switch (verdict) {
    case Verdict::kOk:
      return "ok";
    case Verdict::kBlank:
      return "blank";
    case Verdict::kMalformed:
      return "malformed";
    case Verdict::kOutOfOrder:
      return "out-of-order";
  }
  return "unknown";
}

FrameValidator::FrameValidator(const FrameValidatorOptions& options) : options_(options) {}

Verdict FrameValidator::check(const SourceFrame& frame) {
  if (const auto* rgb = std::get_if<RgbFrame>(&frame)) return check_rgb(*rgb);
  return check_depth(std::get<DepthFrame>(frame));
}

Verdict FrameValidator::check_rgb(const RgbFrame& f) {
  if (f.width != options_.width_px || f.height != options_.height_px ||
      f.rgb.size() != static_cast<std::size_t>(f.width) * f.height * 3) {
    ++counters_.malformed;
    return Verdict::kMalformed;
  }
  if (f.capture_timestamp_us <= last_rgb_us_) {
    ++counters_.out_of_order;
    return Verdict::kOutOfOrder;
  }
  const auto level = static_cast<std::uint8_t>(options_.rgb_black_level);
  if (std::all_of(f.rgb.begin(), f.rgb.end(), [level](std::uint8_t v) { return v <= level; })) {
    ++counters_.rgb_blank;
    return Verdict::kBlank;
  }
  last_rgb_us_ = f.capture_timestamp_us;
  ++counters_.rgb_ok;
  return Verdict::kOk;
}

Verdict FrameValidator::check_depth(const DepthFrame& f) {
  if (f.width != options_.width_px || f.height != options_.height_px ||
      f.depth.size() != static_cast<std::size_t>(f.width) * f.height ||
      !std::isfinite(f.units_per_m) || f.units_per_m <= 0) {
    ++counters_.malformed;
    return Verdict::kMalformed;
  }
  if (f.capture_timestamp_us <= last_depth_us_) {
    ++counters_.out_of_order;
    return Verdict::kOutOfOrder;
  }
  if (std::all_of(f.depth.begin(), f.depth.end(), [](std::uint16_t v) { return v == 0; })) {
    ++counters_.depth_blank;
    return Verdict::kBlank;
  }
  last_depth_us_ = f.capture_timestamp_us;
  ++counters_.depth_ok;
  return Verdict::kOk;
}

}  // namespace rgbdquad::capture
