// Tests of the SURF Feature2D: options, the cv::Feature2D contract, detections on a synthetic
// blob with known position and scale, descriptor norm, determinism and bad input.
#include "rgbdquad/surf/surf.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "descriptor.hpp"
#include "integral_image.hpp"
#include "test_images.hpp"

namespace rgbdquad::surf {
namespace {

TEST(SurfOptions, GivenDefaultsThenThesisParametersAndValid) {
  const SurfOptions o;
  EXPECT_EQ(o.octaves, 4);
  EXPECT_EQ(o.scales_per_octave, 3);
  EXPECT_TRUE(o.extended);
  EXPECT_EQ(o.hessian_threshold, 550.0);
  EXPECT_FALSE(o.upright);
  std::string error;
  EXPECT_TRUE(o.is_valid(&error)) << error;
  std::ostringstream s;
  s << o;
  EXPECT_NE(s.str().find("hessian_threshold=550"), std::string::npos);
}

TEST(SurfOptions, GivenOutOfRangeFieldsWhenValidatedThenErrorNamesTheField) {
  struct Case {
    SurfOptions options;
    const char* field;
  };
  std::vector<Case> cases(4);
  cases[0].options.octaves = 0;
  cases[0].field = "octaves";
  cases[1].options.scales_per_octave = 0;
  cases[1].field = "scales_per_octave";
  cases[2].options.hessian_threshold = -1;
  cases[2].field = "hessian_threshold";
  cases[3].options.hessian_threshold = NAN;
  cases[3].field = "hessian_threshold";
  for (const auto& c : cases) {
    std::string error;
    EXPECT_FALSE(c.options.is_valid(&error));
    EXPECT_NE(error.find(c.field), std::string::npos) << error;
    EXPECT_THROW(create_surf(c.options), std::invalid_argument);
  }
}

TEST(SurfFeature2D, GivenDefaultsThenDescriptorContractIs128FloatL2) {
  auto surf = create_surf({});
  EXPECT_EQ(surf->descriptorSize(), 128);
  EXPECT_EQ(surf->descriptorType(), CV_32F);
  EXPECT_EQ(surf->defaultNorm(), cv::NORM_L2);
  SurfOptions o;
  o.extended = false;
  EXPECT_EQ(create_surf(o)->descriptorSize(), 64);
}

cv::Mat blob_image(double cx, double cy, double sigma_px) {
  cv::Mat img(200, 240, CV_8UC1);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      const double d2 = (c - cx) * (c - cx) + (r - cy) * (r - cy);
      img.at<unsigned char>(r, c) =
          cv::saturate_cast<unsigned char>(30 + 200 * std::exp(-d2 / (2 * sigma_px * sigma_px)));
    }
  return img;
}

TEST(SurfDetect, GivenOneBrightGaussianBlobThenOneKeypointAtItsCentreAndScale) {
  // GIVEN a blob of sigma 3 px centred between pixels
  const double cx = 120.3, cy = 95.6, sigma = 3.0;
  auto surf = create_surf({});
  std::vector<cv::KeyPoint> kps;
  surf->detect(blob_image(cx, cy, sigma), kps);
  // THEN the strongest detection is on it, sub-pixel accurate, with the Laplacian sign of a
  // bright blob. Its nominal scale s = 1.2 size / 9 is ~0.7 sigma: with box lobes normalised by
  // their area (OpenCV's normalisation) the response to a Gaussian blob peaks at a filter of
  // ~5.3 sigma (15-16 px for sigma 3; checked by direct box sums), not at s = sigma.
  ASSERT_FALSE(kps.empty());
  const cv::KeyPoint& kp = kps.front();
  EXPECT_NEAR(kp.pt.x, cx, 0.3);
  EXPECT_NEAR(kp.pt.y, cy, 0.3);
  EXPECT_NEAR(detail::keypoint_scale(kp), 0.7 * sigma, 0.15 * sigma);
  EXPECT_EQ(kp.class_id, -1);
  EXPECT_GT(kp.response, 550.f);
  for (const auto& k : kps) {  // anything else is far weaker (ring artefacts) or elsewhere
    EXPECT_TRUE(&k == &kps.front() || k.response < 0.2f * kp.response ||
                cv::norm(k.pt - kp.pt) > 6.0);
  }
}

TEST(SurfDetect, GivenBlobTwiceAsLargeThenDetectedScaleDoubles) {
  auto surf = create_surf({});
  std::vector<cv::KeyPoint> small, large;
  surf->detect(blob_image(120, 100, 3.0), small);
  surf->detect(blob_image(120, 100, 6.0), large);
  ASSERT_FALSE(small.empty());
  ASSERT_FALSE(large.empty());
  EXPECT_NEAR(large.front().size / small.front().size, 2.0, 0.3);
  EXPECT_NEAR(large.front().pt.x, 120.0, 0.5);
}

TEST(SurfDetect, GivenDarkBlobThenLaplacianSignPositive) {
  cv::Mat img = 255 - blob_image(100, 100, 4.0);
  std::vector<cv::KeyPoint> kps;
  create_surf({})->detect(img, kps);
  ASSERT_FALSE(kps.empty());
  EXPECT_EQ(kps.front().class_id, 1);
}

TEST(SurfDescribe, GivenHaarWaveletOnARampThenResponseIsSlopeTimesWaveletMoment) {
  // I(x, y) = 2x: right half minus left half of a w x w wavelet = 2 * (w/2) * (w/2 * w).
  cv::Mat ramp(40, 60, CV_8UC1);
  for (int r = 0; r < ramp.rows; ++r)
    for (int c = 0; c < ramp.cols; ++c)
      ramp.at<unsigned char>(r, c) = static_cast<unsigned char>(2 * c);
  const detail::IntegralImage ii(ramp);
  for (float x : {20.f, 20.25f, 20.5f, 31.7f}) {
    float dx = 0, dy = 0;
    ASSERT_TRUE(detail::haar_response(ii, x, 17.3f, 6, &dx, &dy));
    EXPECT_NEAR(dx, 2.0 * 3 * 18, 1e-3) << x;
    EXPECT_NEAR(dy, 0.0, 1e-3) << x;
  }
  float dx = 0, dy = 0;
  EXPECT_FALSE(detail::haar_response(ii, 1.f, 20.f, 6, &dx, &dy));  // leaves the image
}

class SurfOnRealFrame : public ::testing::Test {
 protected:
  void SetUp() override {
    gray_ = testing::load_gray(testing::kXyzFrame);
    ASSERT_FALSE(gray_.empty()) << "missing " << testing::kXyzFrame;
  }
  cv::Mat gray_;
};

TEST_F(SurfOnRealFrame, GivenThesisParametersThenSeveralHundredToTwoThousandKeypoints) {
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  create_surf({})->detectAndCompute(gray_, cv::noArray(), kps, desc);
  // Measured: 1190 keypoints on this fr1/xyz frame (723 on the fr1/desk one).
  EXPECT_GE(kps.size(), 500u);
  EXPECT_LE(kps.size(), 2000u);
  ASSERT_EQ(desc.rows, static_cast<int>(kps.size()));
  ASSERT_EQ(desc.cols, 128);
  ASSERT_EQ(desc.type(), CV_32F);
  for (std::size_t i = 0; i < kps.size(); ++i) {
    const auto& k = kps[i];
    ASSERT_GT(k.response, 550.f);
    ASSERT_TRUE(k.class_id == 1 || k.class_id == -1);
    ASSERT_GE(k.angle, 0.f);
    ASSERT_LT(k.angle, 360.f);
    ASSERT_GE(k.octave, 0);
    ASSERT_LT(k.octave, 4);
    ASSERT_TRUE(k.pt.x >= 0 && k.pt.y >= 0 && k.pt.x < 640 && k.pt.y < 480);
    ASSERT_NEAR(cv::norm(desc.row(static_cast<int>(i))), 1.0, 1e-5) << "row " << i;
    if (i > 0) {
      ASSERT_GE(kps[i - 1].response, k.response);  // sorted strongest first
    }
  }
}

TEST_F(SurfOnRealFrame, GivenSameInputTwiceOrOneThreadThenBitIdenticalOutput) {
  auto surf = create_surf({});
  std::vector<cv::KeyPoint> k1, k2, k3;
  cv::Mat d1, d2, d3;
  surf->detectAndCompute(gray_, cv::noArray(), k1, d1);
  surf->detectAndCompute(gray_, cv::noArray(), k2, d2);
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  surf->detectAndCompute(gray_, cv::noArray(), k3, d3);
  cv::setNumThreads(threads);
  for (const auto* other : {&k2, &k3}) {
    ASSERT_EQ(k1.size(), other->size());
    for (std::size_t i = 0; i < k1.size(); ++i) {
      ASSERT_EQ(k1[i].pt, (*other)[i].pt);
      ASSERT_EQ(k1[i].size, (*other)[i].size);
      ASSERT_EQ(k1[i].angle, (*other)[i].angle);
    }
  }
  EXPECT_EQ(cv::norm(d1, d2, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(d1, d3, cv::NORM_INF), 0.0);
}

TEST_F(SurfOnRealFrame, GivenDetectThenComputeThenSameAsDetectAndCompute) {
  auto surf = create_surf({});
  std::vector<cv::KeyPoint> k_all, k_det;
  cv::Mat d_all, d_sep;
  surf->detectAndCompute(gray_, cv::noArray(), k_all, d_all);
  surf->detect(gray_, k_det);
  surf->compute(gray_, k_det, d_sep);
  ASSERT_EQ(k_det.size(), k_all.size());
  EXPECT_EQ(cv::norm(d_all, d_sep, cv::NORM_INF), 0.0);
}

TEST_F(SurfOnRealFrame, GivenColourInputThenSameAsItsGreyConversion) {
  const cv::Mat bgr = cv::imread(testing::kXyzFrame, cv::IMREAD_COLOR);
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  auto surf = create_surf({});
  std::vector<cv::KeyPoint> a, b;
  surf->detect(bgr, a);
  surf->detect(gray, b);
  EXPECT_EQ(a.size(), b.size());
}

TEST_F(SurfOnRealFrame, GivenMaskThenKeypointsOnlyInsideIt) {
  cv::Mat mask = cv::Mat::zeros(gray_.size(), CV_8UC1);
  mask(cv::Rect(0, 0, 320, 480)).setTo(255);
  std::vector<cv::KeyPoint> kps, all;
  auto surf = create_surf({});
  surf->detect(gray_, kps, mask);
  surf->detect(gray_, all);
  ASSERT_FALSE(kps.empty());
  EXPECT_LT(kps.size(), all.size());
  for (const auto& k : kps) EXPECT_LT(k.pt.x, 320.f);
}

TEST_F(SurfOnRealFrame, GivenUprightAnd64dThenAnglesZeroAndUnitNorm) {
  SurfOptions o;
  o.upright = true;
  o.extended = false;
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  create_surf(o)->detectAndCompute(gray_, cv::noArray(), kps, desc);
  ASSERT_FALSE(kps.empty());
  ASSERT_EQ(desc.cols, 64);
  for (int i = 0; i < desc.rows; ++i) {
    ASSERT_EQ(kps[static_cast<std::size_t>(i)].angle, 0.f);
    ASSERT_NEAR(cv::norm(desc.row(i)), 1.0, 1e-5);
  }
}

TEST_F(SurfOnRealFrame, GivenHigherThresholdThenFewerKeypoints) {
  SurfOptions strict;
  strict.hessian_threshold = 2000;
  std::vector<cv::KeyPoint> a, b;
  create_surf({})->detect(gray_, a);
  create_surf(strict)->detect(gray_, b);
  EXPECT_LT(b.size(), a.size());
  EXPECT_GT(b.size(), 0u);
}

TEST(SurfBadInput, GivenUnsupportedImagesThenCvExceptionNotCrash) {
  auto surf = create_surf({});
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  EXPECT_THROW(surf->detect(cv::Mat(48, 64, CV_16UC1, cv::Scalar(0)), kps), cv::Exception);
  EXPECT_THROW(surf->detect(cv::Mat(48, 64, CV_8UC2, cv::Scalar(0)), kps), cv::Exception);
  // Empty and tiny images give no keypoints.
  surf->detectAndCompute(cv::Mat(), cv::noArray(), kps, desc);
  EXPECT_TRUE(kps.empty());
  surf->detectAndCompute(cv::Mat(5, 5, CV_8UC1, cv::Scalar(9)), cv::noArray(), kps, desc);
  EXPECT_TRUE(kps.empty());
  EXPECT_EQ(desc.rows, 0);
  // Provided keypoints that cannot be described are dropped, not crashed on.
  std::vector<cv::KeyPoint> provided = {cv::KeyPoint(10, 10, -3), cv::KeyPoint(NAN, 4, 20),
                                        cv::KeyPoint(30, 30, 20)};
  surf->compute(cv::Mat(64, 64, CV_8UC1, cv::Scalar(9)), provided, desc);
  EXPECT_EQ(provided.size(), 1u);
  EXPECT_EQ(desc.rows, 1);
}

}  // namespace
}  // namespace rgbdquad::surf
