// Global loop closure search (thesis Sec. 3.4), the search half of the thesis' GLC; the back-end
// keeps the other half (adding the loop edge and optimising its pose graph).
//
// Per back-end iteration: test the spread older keyframes (glc_keyframes_to_test), keep the
// accepted match with the most RANSAC inliers (accept_glc_match), then - as the thesis does - also
// test the two keyframes created just before and after that match, which see nearly the same view
// and may register better. The registration itself is the caller's (`compare`), so the search is a
// pure function of what the caller's registration returns and can be tested without images.
// Thread-safe (stateless).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "slam/motion/motion.hpp"
#include "slam/thesis/loop.hpp"

namespace rgbdquad::slam {

/// One keyframe the frame was registered against: descriptor matches and RANSAC's estimate
/// (nullopt: too few pairs or degenerate).
struct KeyframeMatch {
  std::int64_t kf = -1;
  std::size_t matches = 0;
  std::optional<MotionEstimate> est;
};

struct GlcSearchInput {
  std::int64_t frame_id = 0;    ///< the frame (its keyframe id if it just became one)
  std::size_t iteration = 0;    ///< back-end iteration: rotates the candidates (loop.hpp)
  std::size_t n_features = 0;   ///< the frame's features with depth
  std::size_t min_inliers = 0;  ///< the back-end's bar for any usable estimate
  const std::vector<std::int64_t>* recency = nullptr;  ///< keyframe ids, least recently used first
  std::vector<std::int64_t> already_compared;          ///< recent keyframes: not tested again
};

/// Registers the frame against keyframe `kf`; `salt` keeps the RANSAC seeds of the candidate (2)
/// and neighbour (3) passes apart from the recent-keyframe pass (1).
using RegisterAgainst = std::function<KeyframeMatch(std::int64_t kf, std::uint64_t salt)>;
/// The keyframes created just before and after `kf` (fewer at the ends of the sequence).
using CreationNeighbours = std::function<std::vector<std::int64_t>(std::int64_t kf)>;

/// The accepted match with the most inliers (the first on ties), or nullopt when none passed.
std::optional<KeyframeMatch> search_global_loop(const GlcSearchInput& in,
                                                const LoopOptions& options,
                                                const RegisterAgainst& compare,
                                                const CreationNeighbours& neighbours);

}  // namespace rgbdquad::slam
