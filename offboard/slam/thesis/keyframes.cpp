// Keyframe decision; see keyframes.hpp.
#include "slam/thesis/keyframes.hpp"

#include <cmath>

namespace rgbdquad::slam {

bool KeyframeOptions::is_valid(std::string* error) const {
  if (!(fixed_rate_hz > 0) || !std::isfinite(fixed_rate_hz) ||
      !(min_match_fraction >= 0 && min_match_fraction <= 1) ||
      !(min_inlier_fraction >= 0 && min_inlier_fraction <= 1) || recent_keyframes < 1) {
    if (error) *error = "keyframes: options out of range";
    return false;
  }
  return true;
}

bool decide_new_keyframe(const KeyframeOptions& o, std::optional<double> since_last_keyframe_s,
                         const std::optional<KeyframeEvidence>& e) {
  if (!since_last_keyframe_s) return true;  // the first frame always starts the map
  if (o.policy == KeyframePolicy::kFixedRate) {
    // Small tolerance so a 30 Hz stream yields exactly every 10th frame at 3 Hz.
    constexpr double kStampToleranceS = 1e-3;
    return *since_last_keyframe_s + kStampToleranceS >= 1.0 / o.fixed_rate_hz;
  }
  if (!e || e->frame_features == 0 || e->matched_pairs == 0) return true;
  const double match_frac = static_cast<double>(e->matched_pairs) / e->frame_features;
  const double inlier_frac = static_cast<double>(e->inliers) / e->matched_pairs;
  return match_frac < o.min_match_fraction || inlier_frac < o.min_inlier_fraction;
}

}  // namespace rgbdquad::slam
