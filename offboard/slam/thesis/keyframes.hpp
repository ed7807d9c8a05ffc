// Keyframe policy: the two selectable rules of thesis Sec. 3.4 as one pure decision function.
//  - kFixedRate: a new keyframe every 1/rate seconds (thesis: 3 keyframes per second);
//  - kRansac (default): compare the frame with the 3 most recent keyframes; take a new keyframe
//    when, for the best of them, matched pairs < 15 % of the frame's features or RANSAC inliers
//    < 45 % of the pairs (thesis Table 4.4).
// Time is passed in; nothing here reads a clock. Thread-safe (stateless).
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace rgbdquad::slam {

enum class KeyframePolicy { kFixedRate, kRansac };

struct KeyframeOptions {
  KeyframePolicy policy = KeyframePolicy::kRansac;
  double fixed_rate_hz = 3.0;         ///< thesis: 3 keyframes per second
  double min_match_fraction = 0.15;   ///< thesis Table 4.4
  double min_inlier_fraction = 0.45;  ///< thesis Table 4.4
  int recent_keyframes = 3;           ///< thesis: compare with the 3 most recent keyframes
  bool is_valid(std::string* error) const;
};

/// What the comparison with the best recent keyframe found (absent when there is no keyframe yet
/// or no comparison produced a RANSAC estimate).
struct KeyframeEvidence {
  std::size_t frame_features = 0;  ///< features of the current frame (with depth)
  std::size_t matched_pairs = 0;   ///< S-NNMMT pairs with the best recent keyframe
  std::size_t inliers = 0;         ///< RANSAC inliers among those pairs
};

/// Decides whether the current frame becomes a keyframe.
/// `since_last_keyframe_s`: time since the latest keyframe, nullopt when there is none yet.
bool decide_new_keyframe(const KeyframeOptions& options,
                         std::optional<double> since_last_keyframe_s,
                         const std::optional<KeyframeEvidence>& best_recent);

}  // namespace rgbdquad::slam
