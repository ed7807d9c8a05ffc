// Inverted-index keyframe database; see keyframe_database.hpp.
#include "slam/loopclosing/keyframe_database.hpp"

#include <algorithm>

namespace rgbdquad::slam {

void KeyframeDatabase::add(std::int64_t id, BowVector bow) {
  erase(id);
  for (const auto& [w, x] : bow) {
    auto& list = inverted_[w];
    list.insert(std::upper_bound(list.begin(), list.end(), id), id);
  }
  vectors_[id] = std::move(bow);
}

void KeyframeDatabase::erase(std::int64_t id) {
  auto it = vectors_.find(id);
  if (it == vectors_.end()) return;
  for (const auto& [w, x] : it->second) {
    auto& list = inverted_[w];
    list.erase(std::remove(list.begin(), list.end(), id), list.end());
    if (list.empty()) inverted_.erase(w);
  }
  vectors_.erase(it);
}

std::vector<std::int64_t> KeyframeDatabase::ids() const {
  std::vector<std::int64_t> out;
  for (const auto& [id, v] : vectors_) out.push_back(id);
  return out;
}

const BowVector* KeyframeDatabase::vector(std::int64_t id) const {
  auto it = vectors_.find(id);
  return it == vectors_.end() ? nullptr : &it->second;
}

std::vector<KeyframeDatabase::Hit> KeyframeDatabase::query(const BowVector& bow,
                                                           const std::set<std::int64_t>& excluded,
                                                           double min_score,
                                                           std::size_t max_hits) const {
  // Accumulate the L1 score term by term: for non-negative L1-normalised vectors it is the sum over
  // common words of min(a_i, b_i), so only keyframes listed under the query's words are touched.
  std::map<std::int64_t, Hit> acc;
  for (const auto& [w, x] : bow) {
    auto it = inverted_.find(w);
    if (it == inverted_.end()) continue;
    for (std::int64_t kf : it->second) {
      if (excluded.count(kf)) continue;
      const BowVector& v = vectors_.at(kf);
      const auto e =
          std::lower_bound(v.begin(), v.end(), std::make_pair(w, 0.0),
                           [](const auto& a, const auto& b) { return a.first < b.first; });
      Hit& h = acc[kf];
      h.keyframe = kf;
      h.score += std::min(x, e->second);
      ++h.common_words;
    }
  }
  std::vector<Hit> out;
  for (const auto& [kf, h] : acc)
    if (h.score >= min_score) out.push_back(h);
  std::stable_sort(out.begin(), out.end(),
                   [](const Hit& a, const Hit& b) { return a.score > b.score; });
  if (out.size() > max_hits) out.resize(max_hits);
  return out;
}

}  // namespace rgbdquad::slam
