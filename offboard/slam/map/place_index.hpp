// Place recognition by small blurred images, as PTAM's relocaliser does (Klein & Murray 2008:
// each keyframe keeps a 40x30 thumbnail, Gaussian-blurred, zero-mean; a lost frame is compared with
// every keyframe's thumbnail by the sum of squared differences). Cheap (1200 floats per keyframe,
// one pass per query) and needs no trained vocabulary; it ranks candidates, geometry decides.
//
// Stateless and thread-safe.
#pragma once

#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

#include "slam/map/map.hpp"

namespace rgbdquad::slam {

/// 40x30 CV_32F thumbnail of an 8-bit colour or grey image: area-downsampled, blurred (sigma 1.5 px
/// of the thumbnail, 2.5 in PTAM's 1/16 pyramid level), zero mean, unit norm. Empty input: empty.
cv::Mat make_thumbnail(const cv::Mat& image);

/// Dissimilarity in [0, 4]: squared distance of two unit-norm zero-mean thumbnails.
double thumbnail_distance(const cv::Mat& a, const cv::Mat& b);

/// The `k` keyframes whose thumbnails are closest to `thumbnail`, best first.
/// With `below_id`, only keyframes with a smaller id compete (the map before a segment started).
std::vector<std::int64_t> rank_keyframes_by_appearance(
    const SlamMap& map, const cv::Mat& thumbnail, std::size_t k,
    std::int64_t below_id = std::numeric_limits<std::int64_t>::max());

}  // namespace rgbdquad::slam
