// A bag-of-binary-words vocabulary for place recognition (after DBoW2, Galvez-Lopez & Tardos 2012,
// which ORB-SLAM uses; DBoW2/3 are not packaged here, so the project builds its own):
//  - a tree of k branches and L levels built by hierarchical k-majority clustering of binary
//    descriptors (k-medians under the Hamming distance: a cluster centre is the bitwise majority of
//    its members), seeded by k-means++ with an integer-only RNG so that training is bit-identical
//    on every machine;
//  - the leaves are the words; each word carries an idf weight log(N / n_i) (N training images,
//    n_i images containing the word);
//  - an image becomes a tf-idf vector (word -> weight, L1-normalised) by descending the tree with
//    each descriptor; two vectors are compared with DBoW2's L1 score s = 1 - |a - b|_1 / 2 in [0,
//    1], which for non-negative L1-normalised vectors equals the sum over common words of min(a_i,
//    b_i).
// The vocabulary the system uses is trained by `slam-eval vocab` on shipped CC BY TUM frames and
// compiled into the library (see offboard/slam/data/README.md and docs/slam.md).
//
// Immutable after construction; const methods are thread-safe.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace rgbdquad::slam {

/// Sparse tf-idf vector: (word id, weight), sorted by word id, weights summing to 1.
using BowVector = std::vector<std::pair<std::uint32_t, double>>;

/// DBoW2's L1 score of two L1-normalised vectors: 1 identical, 0 nothing in common.
double bow_score(const BowVector& a, const BowVector& b);

struct VocabularyOptions {
  int branching = 10;  ///< k: DBoW2's and ORB-SLAM's ORB vocabulary value
  int levels = 3;  ///< L: ORB-SLAM's is 6 (1e6 words from ~1e7 descriptors); with ~1e4 shippable
                   ///< training descriptors, 3 levels (1000 words) leave ~8 descriptors per word
  int max_iterations = 10;  ///< k-majority rounds per node (stops earlier when assignments settle)
  std::uint64_t seed = 1;
  bool is_valid(std::string* error) const;
};

class BinaryVocabulary {
 public:
  /// Trains on `images`: one CV_8U descriptor matrix per training image (rows = descriptors, all
  /// with the same column count). nullopt with `error` when there is nothing to train on.
  static std::optional<BinaryVocabulary> train(const std::vector<cv::Mat>& images,
                                               const VocabularyOptions& options,
                                               std::string* error);
  /// Reads the byte form written by `to_bytes` (checked: magic, version, sizes, checksum).
  static std::optional<BinaryVocabulary> from_bytes(const std::vector<std::uint8_t>& bytes,
                                                    std::string* error);
  std::vector<std::uint8_t> to_bytes() const;

  /// tf-idf vector of an image's descriptors (CV_8U, descriptor_bytes() columns). Empty input or a
  /// column mismatch gives an empty vector.
  BowVector transform(const cv::Mat& descriptors) const;
  /// Word of one descriptor row (descending the tree, nearest child by Hamming, ties to the lower).
  std::uint32_t word_of(const std::uint8_t* descriptor) const;

  std::size_t words() const { return word_nodes_.size(); }
  int descriptor_bytes() const { return descriptor_bytes_; }
  double idf(std::uint32_t word) const { return idf_[word]; }
  const VocabularyOptions& options() const { return options_; }

 private:
  struct Node {
    std::int32_t parent = -1;
    std::int32_t word = -1;  ///< leaf: its word id
    std::vector<std::int32_t> children;
  };
  BinaryVocabulary() = default;
  void cluster(std::int32_t node, const std::vector<const std::uint8_t*>& members, int level,
               std::uint64_t* rng);
  void finish_words();
  const std::uint8_t* centre(std::int32_t node) const {
    return centres_.data() +
           static_cast<std::size_t>(node) * static_cast<std::size_t>(descriptor_bytes_);
  }

  VocabularyOptions options_;
  int descriptor_bytes_ = 0;
  std::vector<Node> nodes_;               ///< node 0 is the root (no centre used)
  std::vector<std::uint8_t> centres_;     ///< descriptor_bytes_ per node
  std::vector<std::int32_t> word_nodes_;  ///< word id -> node
  std::vector<double> idf_;               ///< per word
};

/// The vocabulary compiled into the library (ORB, trained by `slam-eval vocab`; see docs/slam.md),
/// parsed afresh on each call (~1 ms; callers keep the result). nullopt with `error` if the
/// embedded bytes do not parse (a build defect).
std::optional<BinaryVocabulary> builtin_orb_vocabulary(std::string* error);
/// The embedded bytes themselves (for the test that retraining reproduces them).
std::vector<std::uint8_t> builtin_orb_vocabulary_bytes();

}  // namespace rgbdquad::slam
