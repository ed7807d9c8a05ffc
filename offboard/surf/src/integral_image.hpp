// Summed-area table of an 8-bit grey image (Viola & Jones 2001; SURF section 2.1): any
// axis-aligned box sum in 4 look-ups, independent of the box size.
#pragma once

#include <cstddef>
#include <opencv2/core.hpp>

namespace rgbdquad::surf::detail {

class IntegralImage {
 public:
  /// gray: CV_8UC1. Sums are kept in double, exact for any image size (2^53 > 255 * pixels).
  explicit IntegralImage(const cv::Mat& gray);

  int width() const { return width_; }
  int height() const { return height_; }

  /// Sum of the pixels in [x, x + w) x [y, y + h); the box must lie inside the image
  /// (callers check; an empty box gives 0).
  double box_sum(int x, int y, int w, int h) const {
    const double* top = table_.ptr<double>(y);
    const double* bottom = table_.ptr<double>(y + h);
    return bottom[x + w] - bottom[x] - top[x + w] + top[x];
  }

  /// Row y of the (height + 1) x (width + 1) table; element [x] = sum of pixels above-left.
  const double* row(int y) const { return table_.ptr<double>(y); }
  /// Distance in elements between consecutive rows of the table.
  std::ptrdiff_t stride() const { return static_cast<std::ptrdiff_t>(table_.step1()); }

 private:
  cv::Mat table_;  // CV_64F, (height + 1) x (width + 1), first row and column zero
  int width_;
  int height_;
};

}  // namespace rgbdquad::surf::detail
