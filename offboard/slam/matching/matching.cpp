// Brute-force matching with NNMMT and Lowe's ratio test.
#include "slam/matching/matching.hpp"

#include <cmath>
#include <opencv2/features2d.hpp>

namespace rgbdquad::slam {

bool MatchOptions::is_valid(std::string* error) const {
  if (!(lowe_ratio > 0 && lowe_ratio <= 1) || !(nnmmt_fraction > 0)) {
    if (error) *error = "matching: need 0 < lowe_ratio <= 1 and nnmmt_fraction > 0";
    return false;
  }
  return true;
}

double distance_to_origin(const cv::Mat& row) {
  if (row.type() == CV_8U) return cv::norm(row, cv::NORM_HAMMING);
  return cv::norm(row, cv::NORM_L2);
}

std::vector<Match> match_descriptors(const cv::Mat& query, const cv::Mat& train,
                                     const MatchOptions& o) {
  std::vector<Match> out;
  if (query.empty() || train.empty() || query.type() != train.type() || query.cols != train.cols)
    return out;
  if (query.type() != CV_32F && query.type() != CV_8U) return out;
  const int norm = query.type() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
  cv::BFMatcher matcher(norm, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, train, knn, 2);
  out.reserve(knn.size());
  for (const auto& cand : knn) {
    if (cand.empty()) continue;
    const cv::DMatch& best = cand[0];
    if (o.use_ratio_test) {
      // With a single train descriptor there is no second neighbour: the test cannot pass.
      if (cand.size() < 2) continue;
      if (!(best.distance < o.lowe_ratio * cand[1].distance)) continue;
    }
    if (o.use_nnmmt &&
        best.distance > o.nnmmt_fraction * distance_to_origin(query.row(best.queryIdx)))
      continue;
    out.push_back({best.queryIdx, best.trainIdx, best.distance});
  }
  return out;
}

}  // namespace rgbdquad::slam
