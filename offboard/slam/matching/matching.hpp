// Matching stage: brute-force nearest neighbours from the current frame's descriptors (query) to a
// reference frame's (train), L2 for SIFT/SURF and Hamming for ORB, filtered by
//  - NNMMT (thesis Sec. 3.4): reject a pair whose distance exceeds `nnmmt_fraction` of the distance
//    from the query descriptor to the origin (its L2 norm, or its popcount for binary descriptors);
//  - Lowe's ratio test at `lowe_ratio` (thesis Table 4.4: 0.6); both together are S-NNMMT.
//
// Stateless and thread-safe.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rgbdquad::slam {

struct MatchOptions {
  double lowe_ratio = 0.6;      ///< thesis Table 4.4
  double nnmmt_fraction = 0.5;  ///< "half the distance to the origin", thesis Sec. 3.4
  bool use_nnmmt = true;
  bool use_ratio_test = true;
  bool is_valid(std::string* error) const;
};

struct Match {
  int query = 0;       ///< row in the current frame's descriptors
  int train = 0;       ///< row in the reference frame's descriptors
  float distance = 0;  ///< descriptor distance
};

/// Matches `query` against `train`. Both must have the same type and width (CV_32F or CV_8U);
/// otherwise (or when either is empty) the result is empty.
std::vector<Match> match_descriptors(const cv::Mat& query, const cv::Mat& train,
                                     const MatchOptions& options);

/// Distance of a descriptor row to the origin: L2 norm (float) or number of set bits (binary).
double distance_to_origin(const cv::Mat& descriptor_row);

}  // namespace rgbdquad::slam
