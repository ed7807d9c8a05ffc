// Invariance measurement shared by the tests and surf-bench: warp a frame by a known similarity
// (rotation about the centre + scale), detect and describe both, and measure how many ratio-test
// matches land where the transform says and how repeatable the detections are.
#pragma once

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace rgbdquad::surf::testing {

struct Warped {
  cv::Mat image;
  cv::Matx23d A;  ///< maps original pixel coordinates to warped ones
};

/// Rotates by angle_deg (counter-clockwise as displayed, cv::getRotationMatrix2D) and scales
/// about the centre; the canvas grows/shrinks to hold the whole transformed frame.
inline Warped warp_similarity(const cv::Mat& image, double angle_deg, double scale) {
  const cv::Point2f centre(0.5f * static_cast<float>(image.cols - 1),
                           0.5f * static_cast<float>(image.rows - 1));
  cv::Mat M = cv::getRotationMatrix2D(centre, angle_deg, scale);
  const cv::Rect2f box =
      cv::RotatedRect(centre, cv::Size2f(image.size()) * static_cast<float>(scale),
                      static_cast<float>(-angle_deg))
          .boundingRect2f();
  M.at<double>(0, 2) += 0.5 * box.width - centre.x;
  M.at<double>(1, 2) += 0.5 * box.height - centre.y;
  Warped out;
  out.A = cv::Matx23d(M);
  cv::warpAffine(
      image, out.image, M,
      cv::Size(static_cast<int>(std::lround(box.width)), static_cast<int>(std::lround(box.height))),
      cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return out;
}

inline cv::Point2f apply(const cv::Matx23d& A, const cv::Point2f& p) {
  return {static_cast<float>(A(0, 0) * p.x + A(0, 1) * p.y + A(0, 2)),
          static_cast<float>(A(1, 0) * p.x + A(1, 1) * p.y + A(1, 2))};
}

struct InvarianceResult {
  std::size_t keypoints_original = 0, keypoints_warped = 0;
  std::size_t matches = 0;          ///< passing the ratio test
  std::size_t correct_matches = 0;  ///< within tol_px of the transformed position
  double match_precision = 0.0;     ///< correct_matches / matches
  double repeatability = 0.0;       ///< see evaluate_invariance
};

/// Keypoints more than this far inside the frame border count for repeatability (a detection at
/// the border of one image may be cut by the other's border).
constexpr float kBorderMarginPx = 20.f;

inline bool inside(const cv::Point2f& p, const cv::Size& size, float margin) {
  return p.x >= margin && p.y >= margin && p.x < static_cast<float>(size.width) - margin &&
         p.y < static_cast<float>(size.height) - margin;
}

/// match_precision: BF L2 knn(2) matches passing Lowe's ratio test (ratio) whose warped
/// original point lies within tol_px of the matched point.
/// repeatability: of the original keypoints that land inside the warped frame (and warped
/// keypoints that map back inside the original), the fraction with a detection of the other
/// image within tol_px (the smaller of the two directions' counts), relative to the smaller of
/// the two point counts (as Mikolajczyk et al. 2005, without the region-overlap criterion).
inline InvarianceResult evaluate_invariance(cv::Feature2D& features, const cv::Mat& gray,
                                            double angle_deg, double scale, double ratio,
                                            double tol_px) {
  const Warped warped = warp_similarity(gray, angle_deg, scale);
  std::vector<cv::KeyPoint> kp1, kp2;
  cv::Mat d1, d2;
  features.detectAndCompute(gray, cv::noArray(), kp1, d1);
  features.detectAndCompute(warped.image, cv::noArray(), kp2, d2);
  InvarianceResult r;
  r.keypoints_original = kp1.size();
  r.keypoints_warped = kp2.size();
  if (kp1.empty() || kp2.empty()) return r;

  cv::BFMatcher matcher(features.defaultNorm());
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(d1, d2, knn, 2);
  const double tol_sq = tol_px * tol_px;
  for (const auto& m : knn) {
    if (m.size() < 2 || !(m[0].distance < ratio * m[1].distance)) continue;
    ++r.matches;
    const cv::Point2f expected = apply(warped.A, kp1[static_cast<std::size_t>(m[0].queryIdx)].pt);
    const cv::Point2f d = expected - kp2[static_cast<std::size_t>(m[0].trainIdx)].pt;
    if (d.dot(d) <= tol_sq) ++r.correct_matches;
  }
  r.match_precision =
      r.matches ? static_cast<double>(r.correct_matches) / static_cast<double>(r.matches) : 0.0;

  cv::Matx23d A_inv;
  cv::invertAffineTransform(warped.A, A_inv);
  std::vector<cv::Point2f> p1_in_2, p2_common;
  for (const auto& k : kp1) {
    const cv::Point2f p = apply(warped.A, k.pt);
    if (inside(k.pt, gray.size(), kBorderMarginPx) &&
        inside(p, warped.image.size(), kBorderMarginPx)) {
      p1_in_2.push_back(p);
    }
  }
  for (const auto& k : kp2) {
    if (inside(k.pt, warped.image.size(), kBorderMarginPx) &&
        inside(apply(A_inv, k.pt), gray.size(), kBorderMarginPx)) {
      p2_common.push_back(k.pt);
    }
  }
  // Count, in each direction, the points with a detection of the other image within tol_px;
  // the smaller count bounds the number of one-to-one correspondences.
  auto count_with_neighbour = [&](const std::vector<cv::Point2f>& a,
                                  const std::vector<cv::Point2f>& b) {
    std::size_t n = 0;
    for (const auto& p : a) {
      for (const auto& q : b) {
        const cv::Point2f d = p - q;
        if (d.dot(d) <= tol_sq) {
          ++n;
          break;
        }
      }
    }
    return n;
  };
  const std::size_t repeated =
      std::min(count_with_neighbour(p1_in_2, p2_common), count_with_neighbour(p2_common, p1_in_2));
  const std::size_t denom = std::min(p1_in_2.size(), p2_common.size());
  r.repeatability = denom ? static_cast<double>(repeated) / static_cast<double>(denom) : 0.0;
  return r;
}

}  // namespace rgbdquad::surf::testing
