// Integral image construction (see integral_image.hpp).
#include "integral_image.hpp"

#include <opencv2/imgproc.hpp>

namespace rgbdquad::surf::detail {

IntegralImage::IntegralImage(const cv::Mat& gray) : width_(gray.cols), height_(gray.rows) {
  CV_Assert(gray.type() == CV_8UC1);
  cv::integral(gray, table_, CV_64F);
}

}  // namespace rgbdquad::surf::detail
