// Unit tests of the integral image and the SURF box filters against direct pixel sums.
#include "integral_image.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

#include "hessian.hpp"

namespace rgbdquad::surf::detail {
namespace {

cv::Mat random_image(int rows, int cols, int seed) {
  cv::Mat img(rows, cols, CV_8UC1);
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  return img;
}

double direct_sum(const cv::Mat& img, int x, int y, int w, int h) {
  double s = 0.0;
  for (int r = y; r < y + h; ++r)
    for (int c = x; c < x + w; ++c) s += img.at<unsigned char>(r, c);
  return s;
}

TEST(IntegralImage, GivenRandomImageWhenBoxSumThenEqualsDirectSum) {
  const cv::Mat img = random_image(37, 53, 7);
  const IntegralImage ii(img);
  EXPECT_EQ(ii.width(), 53);
  EXPECT_EQ(ii.height(), 37);
  cv::RNG rng(11);
  for (int k = 0; k < 500; ++k) {
    const int x = rng.uniform(0, 53), y = rng.uniform(0, 37);
    const int w = rng.uniform(0, 53 - x + 1), h = rng.uniform(0, 37 - y + 1);
    ASSERT_EQ(ii.box_sum(x, y, w, h), direct_sum(img, x, y, w, h)) << x << "," << y;
  }
  EXPECT_EQ(ii.box_sum(0, 0, 53, 37), cv::sum(img)[0]);
  EXPECT_EQ(ii.box_sum(5, 5, 0, 3), 0.0);
}

TEST(IntegralImage, GivenLargeWhiteImageWhenSummedThenExactBeyondInt32) {
  // 9000 x 1000 x 255 = 2.3e9 > INT32_MAX: the double table must stay exact.
  const cv::Mat img(1000, 9000, CV_8UC1, cv::Scalar(255));
  const IntegralImage ii(img);
  EXPECT_EQ(ii.box_sum(0, 0, 9000, 1000), 255.0 * 9000.0 * 1000.0);
}

TEST(HessianKernel, GivenSize9And15WhenBuiltThenLobesMatchThePaper) {
  // Bay et al. 2008 Fig. 1 / section 3.3: 9x9 Dyy has lobes 3 px long and 5 px wide; at 15 the
  // lobes are 5 long and 9 wide; Dxy lobes are l0 x l0 with a 1 px gap on the centre lines.
  const auto k9 = make_hessian_kernel(0, 0);
  EXPECT_EQ(k9.size, 9);
  ASSERT_EQ(k9.dyy.size(), 3u);
  EXPECT_EQ(k9.dyy[1].x0, 2);
  EXPECT_EQ(k9.dyy[1].x1, 7);
  EXPECT_EQ(k9.dyy[1].y0, 3);
  EXPECT_EQ(k9.dyy[1].y1, 6);
  EXPECT_FLOAT_EQ(k9.dyy[1].weight, -2.f / 15.f);
  ASSERT_EQ(k9.dxy.size(), 4u);
  EXPECT_EQ(k9.dxy[0].x0, 1);
  EXPECT_EQ(k9.dxy[0].x1, 4);
  EXPECT_EQ(k9.dxy[1].x0, 5);
  EXPECT_FLOAT_EQ(k9.dxy[1].weight, -1.f / 9.f);
  const auto k15 = make_hessian_kernel(0, 1);
  EXPECT_EQ(k15.size, 15);
  EXPECT_EQ(k15.dxx[0].x1 - k15.dxx[0].x0, 5);
  EXPECT_EQ(k15.dxx[0].y1 - k15.dxx[0].y0, 9);
  // Octave 2 layer 0 is the 9x9 filter scaled by 2: 18 px.
  const auto k18 = make_hessian_kernel(1, 0);
  EXPECT_EQ(k18.size, 18);
  EXPECT_EQ(k18.dxy[1].x0, 10);
  EXPECT_EQ(filter_size(3, 4), 33 * 8);
}

TEST(HessianKernel, GivenAnyKernelThenLobesStayInsideAndWeightsCancelOnFlatImages) {
  for (int octave = 0; octave < 4; ++octave) {
    for (int layer = 0; layer < 5; ++layer) {
      const auto k = make_hessian_kernel(octave, layer);
      for (const auto* part : {&k.dxx, &k.dyy, &k.dxy}) {
        double flat = 0.0;
        for (const auto& b : *part) {
          EXPECT_GE(b.x0, 0);
          EXPECT_GE(b.y0, 0);
          EXPECT_LE(b.x1, k.size);
          EXPECT_LE(b.y1, k.size);
          flat += b.weight * (b.x1 - b.x0) * (b.y1 - b.y0);  // response to intensity 1
        }
        EXPECT_NEAR(flat, 0.0, 1e-6) << "octave " << octave << " layer " << layer;
      }
    }
  }
}

TEST(HessianLayer, GivenRandomImageWhenComputedThenEqualsDirectBoxFilterSums) {
  const cv::Mat img = random_image(70, 90, 3);
  const IntegralImage ii(img);
  for (const auto& [octave, layer] : {std::pair{0, 0}, std::pair{0, 2}, std::pair{1, 1}}) {
    const HessianLayer hl = compute_hessian_layer(ii, octave, layer);
    const HessianKernel k = make_hessian_kernel(octave, layer);
    ASSERT_TRUE(hl.valid());
    const int half = (k.size - hl.step) / 2;
    for (int r = hl.row_min; r <= hl.row_max; r += 3) {
      for (int c = hl.col_min; c <= hl.col_max; c += 4) {
        const int x0 = c * hl.step - half, y0 = r * hl.step - half;
        ASSERT_GE(x0, 0);
        ASSERT_LE(x0 + k.size, img.cols);
        auto direct = [&](const std::vector<HaarBox>& boxes) {
          double s = 0.0;
          for (const auto& b : boxes)
            s += b.weight * direct_sum(img, x0 + b.x0, y0 + b.y0, b.x1 - b.x0, b.y1 - b.y0);
          return s;
        };
        const double dxx = direct(k.dxx), dyy = direct(k.dyy), dxy = direct(k.dxy);
        EXPECT_NEAR(hl.det_at(r, c), dxx * dyy - 0.81 * dxy * dxy,
                    1e-2 + 1e-5 * std::abs(dxx * dyy));
        EXPECT_NEAR(hl.trace_at(r, c), dxx + dyy, 1e-3);
        EXPECT_NEAR(box_filter_response(ii, k.dxx, x0, y0), dxx, 1e-6);
      }
    }
    // The first invalid column on the right would need pixels beyond the image.
    EXPECT_GT((hl.col_max + 1) * hl.step - half + k.size, img.cols);
  }
}

TEST(HessianLayer, GivenBrightBlobWhenComputedThenDeterminantPeaksAtItsCentreWithNegativeTrace) {
  // A Gaussian blob of sigma 2 px; the 9x9 filter (sigma 1.2) .. 21x21 respond most near it.
  cv::Mat img(64, 64, CV_8UC1, cv::Scalar(20));
  for (int r = 0; r < 64; ++r)
    for (int c = 0; c < 64; ++c)
      img.at<unsigned char>(r, c) = static_cast<unsigned char>(
          20 + 200 * std::exp(-((r - 32) * (r - 32) + (c - 30) * (c - 30)) / 8.0));
  const IntegralImage ii(img);
  const HessianLayer hl = compute_hessian_layer(ii, 0, 0);
  int best_r = 0, best_c = 0;
  for (int r = hl.row_min; r <= hl.row_max; ++r)
    for (int c = hl.col_min; c <= hl.col_max; ++c)
      if (hl.det_at(r, c) > hl.det_at(best_r, best_c)) best_r = r, best_c = c;
  EXPECT_EQ(best_r, 32);
  EXPECT_EQ(best_c, 30);
  EXPECT_LT(hl.trace_at(best_r, best_c), 0.f);
  const HessianLayer tiny = compute_hessian_layer(IntegralImage(img(cv::Rect(0, 0, 8, 8))), 0, 0);
  EXPECT_FALSE(tiny.valid());  // a 9 px filter does not fit an 8 px image
}

}  // namespace
}  // namespace rgbdquad::surf::detail
