// JPEG RGB codec: real frames compress, decode to the right size with bounded error; bad input
// is rejected with a message.
#include "rgbdquad/encodings/jpeg_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rgbdquad::encodings {
namespace {

constexpr const char* kRgbPng = RGBD_TEST_DATA_DIR "/fr1_xyz_first30/rgb/1305031102.175304.png";

TEST(JpegCodec, RealFrameRoundTripHasSmallError) {
  cv::Mat bgr = cv::imread(kRgbPng, cv::IMREAD_COLOR);
  ASSERT_FALSE(bgr.empty());
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  JpegEncoder encoder(90);
  JpegDecoder decoder;
  std::string error;
  const auto jpeg = encoder.encode(rgb.data, rgb.cols, rgb.rows, &error);
  ASSERT_TRUE(jpeg.has_value()) << error;
  EXPECT_LT(jpeg->size(), rgb.total() * 3 / 5) << "quality 90 should compress > 5:1";
  const auto back = decoder.decode(jpeg->data(), jpeg->size(), rgb.cols, rgb.rows, &error);
  ASSERT_TRUE(back.has_value()) << error;
  ASSERT_EQ(back->size(), rgb.total() * 3);
  double sum_sq = 0;
  for (std::size_t i = 0; i < back->size(); ++i) {
    const double d = static_cast<double>((*back)[i]) - rgb.data[i];
    sum_sq += d * d;
  }
  const double psnr = 10 * std::log10(255.0 * 255.0 / (sum_sq / back->size()));
  EXPECT_GT(psnr, 30.0);  // quality 90 on natural images gives ~35-40 dB
}

TEST(JpegCodec, RejectsGarbageTruncationAndWrongSize) {
  std::vector<std::uint8_t> rgb(64 * 48 * 3, 100);
  JpegEncoder encoder(80);
  JpegDecoder decoder;
  std::string error;
  const auto jpeg = encoder.encode(rgb.data(), 64, 48, &error);
  ASSERT_TRUE(jpeg.has_value());
  EXPECT_FALSE(decoder.decode(jpeg->data(), jpeg->size(), 64, 49, &error).has_value());
  EXPECT_NE(error.find("64x48"), std::string::npos);
  EXPECT_FALSE(decoder.decode(jpeg->data(), jpeg->size() / 2, 64, 48, &error).has_value());
  const std::vector<std::uint8_t> garbage(100, 0x42);
  EXPECT_FALSE(decoder.decode(garbage.data(), garbage.size(), 64, 48, &error).has_value());
  EXPECT_THROW(JpegEncoder(0), std::runtime_error);
  EXPECT_THROW(JpegEncoder(101), std::runtime_error);
}

}  // namespace
}  // namespace rgbdquad::encodings
