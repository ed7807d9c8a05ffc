// Place recognition over all keyframes: an inverted index (word -> keyframes containing it) over
// the keyframes' bag-of-words vectors, scored with DBoW2's L1 score (vocabulary.hpp). A query only
// touches keyframes that share a word with it, so its cost grows with the matching entries, not
// with the map (ORB-SLAM2's KeyFrameDatabase).
//
// Not thread-safe: owned by the loop closer.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <unordered_map>
#include <utility>
#include <vector>

#include "slam/loopclosing/vocabulary.hpp"

namespace rgbdquad::slam {

class KeyframeDatabase {
 public:
  /// Adds (or replaces) keyframe `id` with its vector.
  void add(std::int64_t id, BowVector bow);
  void erase(std::int64_t id);
  bool contains(std::int64_t id) const { return vectors_.count(id) != 0; }
  const BowVector* vector(std::int64_t id) const;
  std::size_t size() const { return vectors_.size(); }
  std::vector<std::int64_t> ids() const;

  struct Hit {
    std::int64_t keyframe = -1;
    double score = 0;
    int common_words = 0;
  };
  /// Keyframes scoring at least `min_score` against `bow`, except those in `excluded`; best first
  /// (ties: the older keyframe first), at most `max_hits`.
  std::vector<Hit> query(const BowVector& bow, const std::set<std::int64_t>& excluded,
                         double min_score, std::size_t max_hits) const;

 private:
  std::unordered_map<std::uint32_t, std::vector<std::int64_t>>
      inverted_;  ///< word -> keyframes (sorted)
  std::map<std::int64_t, BowVector> vectors_;
};

}  // namespace rgbdquad::slam
