// Thumbnail place recognition; see place_index.hpp.
#include "slam/map/place_index.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace rgbdquad::slam {

cv::Mat make_thumbnail(const cv::Mat& image) {
  if (image.empty()) return {};
  cv::Mat grey;
  if (image.channels() == 3)
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  else
    grey = image;
  cv::Mat small, f;
  cv::resize(grey, small, cv::Size(40, 30), 0, 0, cv::INTER_AREA);
  small.convertTo(f, CV_32F);
  cv::GaussianBlur(f, f, cv::Size(0, 0), 1.5);
  f -= cv::mean(f)[0];
  const double n = cv::norm(f);
  if (n > 1e-6) f /= n;
  return f;
}

double thumbnail_distance(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty() || a.size() != b.size()) return 4.0;
  const double d = cv::norm(a, b, cv::NORM_L2);
  return d * d;
}

std::vector<std::int64_t> rank_keyframes_by_appearance(const SlamMap& map, const cv::Mat& thumbnail,
                                                       std::size_t k, std::int64_t below_id) {
  std::vector<std::pair<double, std::int64_t>> scored;
  for (const auto& [id, kf] : map.keyframes())
    if (id < below_id) scored.emplace_back(thumbnail_distance(thumbnail, kf.thumbnail), id);
  std::sort(scored.begin(), scored.end());
  std::vector<std::int64_t> out;
  for (std::size_t i = 0; i < scored.size() && i < k; ++i) out.push_back(scored[i].second);
  return out;
}

}  // namespace rgbdquad::slam
