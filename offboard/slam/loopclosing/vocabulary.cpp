// Bag-of-binary-words vocabulary; see vocabulary.hpp.
#include "slam/loopclosing/vocabulary.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <set>

#include "slam/map/map_io.hpp"

namespace rgbdquad::slam {

namespace {

constexpr char kVocabMagic[8] = {'R', 'G', 'B', 'D', 'Q', 'V', 'O', 'C'};
constexpr std::uint32_t kVocabFileVersion = 1;
constexpr std::size_t kMaxVocabNodes = 2000000;  // far above k^L for any sensible k, L
constexpr int kMaxDescriptorBytes = 256;

int hamming(const std::uint8_t* a, const std::uint8_t* b, int bytes) {
  int d = 0;
  int i = 0;
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t x, y;
    std::memcpy(&x, a + i, 8);
    std::memcpy(&y, b + i, 8);
    d += __builtin_popcountll(x ^ y);
  }
  for (; i < bytes; ++i) d += __builtin_popcount(static_cast<unsigned>(a[i] ^ b[i]));
  return d;
}

/// splitmix64: integer-only, so training is identical on every platform and standard library.
std::uint64_t next_random(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

template <typename T>
void put(std::vector<std::uint8_t>* out, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out->insert(out->end(), b, b + sizeof(T));
}

template <typename T>
bool get(const std::vector<std::uint8_t>& in, std::size_t end, std::size_t* pos, T* v) {
  if (end - *pos < sizeof(T)) return false;
  std::memcpy(v, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return true;
}

}  // namespace

double bow_score(const BowVector& a, const BowVector& b) {
  double s = 0;
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (i->first < j->first)
      ++i;
    else if (j->first < i->first)
      ++j;
    else {
      s += std::min(i->second, j->second);
      ++i;
      ++j;
    }
  }
  return s;
}

bool VocabularyOptions::is_valid(std::string* error) const {
  if (branching < 2 || levels < 1 || max_iterations < 1) {
    if (error) *error = "vocabulary: branching >= 2, levels >= 1, iterations >= 1";
    return false;
  }
  double nodes = 1, level = 1;
  for (int l = 0; l < levels; ++l) nodes += (level *= branching);
  if (nodes > static_cast<double>(kMaxVocabNodes)) {
    if (error) *error = "vocabulary: branching^levels too large";
    return false;
  }
  return true;
}

std::optional<BinaryVocabulary> BinaryVocabulary::train(const std::vector<cv::Mat>& images,
                                                        const VocabularyOptions& options,
                                                        std::string* error) {
  if (!options.is_valid(error)) return std::nullopt;
  BinaryVocabulary v;
  v.options_ = options;
  std::vector<const std::uint8_t*> all;
  for (const cv::Mat& m : images) {
    if (m.empty()) continue;
    if (m.type() != CV_8U || !m.isContinuous() ||
        (v.descriptor_bytes_ != 0 && m.cols != v.descriptor_bytes_) ||
        m.cols > kMaxDescriptorBytes) {
      if (error)
        *error = "vocabulary: training descriptors must be continuous CV_8U rows of one width";
      return std::nullopt;
    }
    v.descriptor_bytes_ = m.cols;
    for (int r = 0; r < m.rows; ++r) all.push_back(m.ptr<std::uint8_t>(r));
  }
  if (all.empty()) {
    if (error) *error = "vocabulary: no training descriptors";
    return std::nullopt;
  }
  v.nodes_.emplace_back();
  v.centres_.assign(static_cast<std::size_t>(v.descriptor_bytes_), 0);
  std::uint64_t rng = options.seed;
  v.cluster(0, all, 0, &rng);
  v.finish_words();
  // idf = log(N / n_i): N training images, n_i of them containing word i (DBoW2's TF_IDF).
  std::vector<int> images_with(v.words(), 0);
  int n_images = 0;
  for (const cv::Mat& m : images) {
    if (m.empty()) continue;
    ++n_images;
    std::set<std::uint32_t> seen;
    for (int r = 0; r < m.rows; ++r) seen.insert(v.word_of(m.ptr<std::uint8_t>(r)));
    for (std::uint32_t w : seen) ++images_with[w];
  }
  v.idf_.resize(v.words());
  for (std::size_t w = 0; w < v.words(); ++w)
    v.idf_[w] = std::log(static_cast<double>(n_images) / std::max(1, images_with[w]));
  return v;
}

void BinaryVocabulary::cluster(std::int32_t node, const std::vector<const std::uint8_t*>& members,
                               int level, std::uint64_t* rng) {
  if (level >= options_.levels || members.size() <= 1) return;
  const int bytes = descriptor_bytes_;
  const auto k = static_cast<std::size_t>(options_.branching);
  auto add_child = [&](const std::uint8_t* c) {
    const auto id = static_cast<std::int32_t>(nodes_.size());
    Node n;
    n.parent = node;
    nodes_.push_back(n);
    nodes_[static_cast<std::size_t>(node)].children.push_back(id);
    centres_.insert(centres_.end(), c, c + bytes);
    return id;
  };
  if (members.size() <= k) {  // DBoW2: few descriptors -> one word each
    for (const std::uint8_t* m : members) add_child(m);
    return;
  }
  // k-means++ seeding on integer squared Hamming distances.
  std::vector<std::vector<std::uint8_t>> centres;
  {
    const std::uint8_t* first = members[next_random(rng) % members.size()];
    centres.emplace_back(first, first + bytes);
  }
  std::vector<std::uint64_t> d2(members.size());
  for (std::size_t i = 0; i < members.size(); ++i) {
    const auto d = static_cast<std::uint64_t>(hamming(members[i], centres[0].data(), bytes));
    d2[i] = d * d;
  }
  while (centres.size() < k) {
    std::uint64_t total = 0;
    for (std::uint64_t x : d2) total += x;
    if (total == 0) break;  // every member equals a centre already
    const std::uint64_t r = next_random(rng) % total;
    std::uint64_t acc = 0;
    std::size_t pick = 0;
    for (; pick < members.size(); ++pick) {
      acc += d2[pick];
      if (acc > r) break;
    }
    centres.emplace_back(members[pick], members[pick] + bytes);
    for (std::size_t i = 0; i < members.size(); ++i) {
      const auto d = static_cast<std::uint64_t>(hamming(members[i], centres.back().data(), bytes));
      d2[i] = std::min(d2[i], d * d);
    }
  }
  // k-majority iterations: assign to the nearest centre, centre = bitwise majority of its members.
  std::vector<int> assign(members.size(), -1);
  for (int it = 0; it < options_.max_iterations; ++it) {
    bool changed = false;
    for (std::size_t i = 0; i < members.size(); ++i) {
      int best = 0, best_d = hamming(members[i], centres[0].data(), bytes);
      for (std::size_t c = 1; c < centres.size(); ++c) {
        const int d = hamming(members[i], centres[c].data(), bytes);
        if (d < best_d) {
          best_d = d;
          best = static_cast<int>(c);
        }
      }
      if (assign[i] != best) {
        assign[i] = best;
        changed = true;
      }
    }
    if (!changed) break;
    for (std::size_t c = 0; c < centres.size(); ++c) {
      std::vector<int> ones(static_cast<std::size_t>(bytes) * 8, 0);
      int n = 0;
      for (std::size_t i = 0; i < members.size(); ++i) {
        if (assign[i] != static_cast<int>(c)) continue;
        ++n;
        for (int b = 0; b < bytes * 8; ++b)
          ones[static_cast<std::size_t>(b)] += (members[i][b / 8] >> (b % 8)) & 1;
      }
      if (n == 0) continue;  // an empty cluster keeps its centre
      std::fill(centres[c].begin(), centres[c].end(), 0);
      for (int b = 0; b < bytes * 8; ++b)
        if (2 * ones[static_cast<std::size_t>(b)] > n)
          centres[c][static_cast<std::size_t>(b / 8)] |= static_cast<std::uint8_t>(1u << (b % 8));
    }
  }
  for (std::size_t c = 0; c < centres.size(); ++c) {
    std::vector<const std::uint8_t*> sub;
    for (std::size_t i = 0; i < members.size(); ++i)
      if (assign[i] == static_cast<int>(c)) sub.push_back(members[i]);
    if (sub.empty()) continue;
    const std::int32_t child = add_child(centres[c].data());
    cluster(child, sub, level + 1, rng);
  }
}

void BinaryVocabulary::finish_words() {
  word_nodes_.clear();
  for (std::size_t i = 1; i < nodes_.size(); ++i)
    if (nodes_[i].children.empty()) {
      nodes_[i].word = static_cast<std::int32_t>(word_nodes_.size());
      word_nodes_.push_back(static_cast<std::int32_t>(i));
    }
}

std::uint32_t BinaryVocabulary::word_of(const std::uint8_t* d) const {
  std::int32_t node = 0;
  while (!nodes_[static_cast<std::size_t>(node)].children.empty()) {
    const auto& ch = nodes_[static_cast<std::size_t>(node)].children;
    std::int32_t best = ch[0];
    int best_d = hamming(d, centre(best), descriptor_bytes_);
    for (std::size_t c = 1; c < ch.size(); ++c) {
      const int dist = hamming(d, centre(ch[c]), descriptor_bytes_);
      if (dist < best_d) {
        best_d = dist;
        best = ch[c];
      }
    }
    node = best;
  }
  return static_cast<std::uint32_t>(std::max(0, nodes_[static_cast<std::size_t>(node)].word));
}

BowVector BinaryVocabulary::transform(const cv::Mat& descriptors) const {
  BowVector out;
  if (descriptors.empty() || descriptors.type() != CV_8U || descriptors.cols != descriptor_bytes_ ||
      words() == 0)
    return out;
  std::map<std::uint32_t, int> counts;
  for (int r = 0; r < descriptors.rows; ++r) ++counts[word_of(descriptors.ptr<std::uint8_t>(r))];
  double sum = 0;
  for (const auto& [w, n] : counts) {
    const double weight = n * idf_[w];  // tf's 1/rows cancels in the L1 normalisation
    if (weight <= 0) continue;          // a word in every training image says nothing
    out.emplace_back(w, weight);
    sum += weight;
  }
  for (auto& [w, x] : out) x /= sum;
  return out;
}

std::vector<std::uint8_t> BinaryVocabulary::to_bytes() const {
  std::vector<std::uint8_t> b(kVocabMagic, kVocabMagic + sizeof kVocabMagic);
  put<std::uint32_t>(&b, kVocabFileVersion);
  put<std::int32_t>(&b, options_.branching);
  put<std::int32_t>(&b, options_.levels);
  put<std::int32_t>(&b, options_.max_iterations);
  put<std::uint64_t>(&b, options_.seed);
  put<std::int32_t>(&b, descriptor_bytes_);
  put<std::uint32_t>(&b, static_cast<std::uint32_t>(nodes_.size()));
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    put<std::int32_t>(&b, nodes_[i].parent);
    const std::uint8_t* c = centre(static_cast<std::int32_t>(i));
    b.insert(b.end(), c, c + descriptor_bytes_);
  }
  put<std::uint32_t>(&b, static_cast<std::uint32_t>(idf_.size()));
  for (double x : idf_) put<double>(&b, x);
  put<std::uint64_t>(&b, fnv1a64(b.data(), b.size()));
  return b;
}

std::optional<BinaryVocabulary> BinaryVocabulary::from_bytes(const std::vector<std::uint8_t>& b,
                                                             std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = "vocabulary: " + why;
    return std::nullopt;
  };
  if (b.size() < sizeof kVocabMagic + 12 ||
      std::memcmp(b.data(), kVocabMagic, sizeof kVocabMagic) != 0)
    return fail("bad magic");
  std::uint64_t stored = 0;
  std::memcpy(&stored, b.data() + b.size() - 8, 8);
  if (fnv1a64(b.data(), b.size() - 8) != stored) return fail("checksum mismatch");
  const std::size_t end = b.size() - 8;
  std::size_t pos = sizeof kVocabMagic;
  std::uint32_t version = 0, n_nodes = 0, n_words = 0;
  BinaryVocabulary v;
  if (!get(b, end, &pos, &version) || version != kVocabFileVersion) return fail("unknown version");
  if (!get(b, end, &pos, &v.options_.branching) || !get(b, end, &pos, &v.options_.levels) ||
      !get(b, end, &pos, &v.options_.max_iterations) || !get(b, end, &pos, &v.options_.seed) ||
      !get(b, end, &pos, &v.descriptor_bytes_) || !get(b, end, &pos, &n_nodes))
    return fail("truncated header");
  if (v.descriptor_bytes_ < 1 || v.descriptor_bytes_ > kMaxDescriptorBytes || n_nodes < 1 ||
      n_nodes > kMaxVocabNodes)
    return fail("sizes out of range");
  v.nodes_.resize(n_nodes);
  v.centres_.resize(static_cast<std::size_t>(n_nodes) *
                    static_cast<std::size_t>(v.descriptor_bytes_));
  for (std::uint32_t i = 0; i < n_nodes; ++i) {
    std::int32_t parent = 0;
    if (!get(b, end, &pos, &parent)) return fail("truncated node");
    if ((i == 0) != (parent < 0) || parent >= static_cast<std::int32_t>(i))
      return fail("node order");
    v.nodes_[i].parent = parent;
    if (parent >= 0)
      v.nodes_[static_cast<std::size_t>(parent)].children.push_back(static_cast<std::int32_t>(i));
    const auto bytes = static_cast<std::size_t>(v.descriptor_bytes_);
    if (end - pos < bytes) return fail("truncated centre");
    std::memcpy(v.centres_.data() + i * bytes, b.data() + pos, bytes);
    pos += bytes;
  }
  v.finish_words();
  if (!get(b, end, &pos, &n_words) || n_words != v.words()) return fail("word count");
  v.idf_.resize(n_words);
  for (double& x : v.idf_)
    if (!get(b, end, &pos, &x) || !std::isfinite(x)) return fail("idf");
  if (pos != end) return fail("trailing bytes");
  return v;
}

}  // namespace rgbdquad::slam
