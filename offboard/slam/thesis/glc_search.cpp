// Global loop closure search: see glc_search.hpp.
#include "slam/thesis/glc_search.hpp"

#include <algorithm>

namespace rgbdquad::slam {

namespace {
constexpr std::uint64_t kCandidateSalt = 2;
constexpr std::uint64_t kNeighbourSalt = 3;
}  // namespace

std::optional<KeyframeMatch> search_global_loop(const GlcSearchInput& in,
                                                const LoopOptions& options,
                                                const RegisterAgainst& compare,
                                                const CreationNeighbours& neighbours) {
  if (in.recency == nullptr) return std::nullopt;
  auto accepted = [&](const KeyframeMatch& m) {
    return m.est && accept_glc_match(options, in.n_features, m.matches, m.est->inlier_ratio,
                                     m.est->inliers.size(), in.min_inliers);
  };
  auto better = [](const KeyframeMatch& m, const std::optional<KeyframeMatch>& best) {
    return !best || m.est->inliers.size() > best->est->inliers.size();
  };
  std::optional<KeyframeMatch> found;
  for (std::int64_t kf : glc_keyframes_to_test(*in.recency, in.frame_id, in.iteration, options)) {
    KeyframeMatch m = compare(kf, kCandidateSalt);
    if (accepted(m) && better(m, found)) found = std::move(m);
  }
  if (!found || !options.glc_test_neighbours) return found;
  for (std::int64_t nid : neighbours(found->kf)) {
    if (nid == in.frame_id) continue;
    if (std::find(in.already_compared.begin(), in.already_compared.end(), nid) !=
        in.already_compared.end())
      continue;
    KeyframeMatch m = compare(nid, kNeighbourSalt);
    if (accepted(m) && better(m, found)) found = std::move(m);
  }
  return found;
}

}  // namespace rgbdquad::slam
