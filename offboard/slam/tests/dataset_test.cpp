// Dataset reader: association within 20 ms, rate reduction, clear errors for bad folders.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "rgbdquad/encodings/jpeg_codec.h"
#include "slam/dataset/tum_dataset.hpp"

namespace rgbdquad::slam {
namespace {

const std::string kExcerpt = std::string(SLAM_REPO_DIR) + "/tests/data/fr1_xyz_first30";

TEST(TumDataset, GivenShippedExcerptThenFramesAssociatedWithin20ms) {
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  EXPECT_GE(ds->size(), 28u);
  EXPECT_LE(ds->size(), 30u);
  for (std::size_t i = 0; i < ds->size(); ++i)
    EXPECT_LE(std::abs(ds->entry(i).rgb_stamp_s - ds->entry(i).depth_stamp_s), 0.02);
  EXPECT_FALSE(ds->groundtruth_path().empty());
  EXPECT_NEAR(ds->frame_period_s(), 1.0 / 30, 0.01);
  auto f = ds->load(0, &err);
  ASSERT_TRUE(f) << err;
  EXPECT_EQ(f->depth.type(), CV_16UC1);
  EXPECT_EQ(f->rgb.cols, 640);
}

TEST(TumDataset, GivenRateDivisorThenEveryKthFrameKept) {
  TumDatasetOptions o;
  auto all = TumDataset::open(kExcerpt, o, nullptr);
  o.rate_divisor = 3;
  auto third = TumDataset::open(kExcerpt, o, nullptr);
  ASSERT_TRUE(all && third);
  EXPECT_EQ(third->size(), (all->size() + 2) / 3);
  EXPECT_EQ(third->entry(1).rgb_stamp_s, all->entry(3).rgb_stamp_s);
  EXPECT_NEAR(third->frame_period_s(), 3.0 / 30, 0.02);
}

TEST(TumDataset, GivenBadInputThenClearErrors) {
  std::string err;
  EXPECT_FALSE(TumDataset::open("/nonexistent/folder", TumDatasetOptions{}, &err));
  EXPECT_NE(err.find("does not exist"), std::string::npos);
  // Unique per process so parallel test runs never share the folder.
  const auto tmp = std::filesystem::temp_directory_path() /
                   ("slam_dataset_test_bad_" + std::to_string(::getpid()));
  std::filesystem::create_directories(tmp);
  std::ofstream(tmp / "rgb.txt") << "# header\n1.0 rgb/missing.png\n";
  EXPECT_FALSE(TumDataset::open(tmp.string(), TumDatasetOptions{}, &err));
  EXPECT_NE(err.find("depth.txt"), std::string::npos);
  std::ofstream(tmp / "depth.txt") << "1.005 depth/missing.png\n";
  auto ds = TumDataset::open(tmp.string(), TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  EXPECT_FALSE(ds->load(0, &err));
  EXPECT_NE(err.find("missing.png"), std::string::npos);
  std::ofstream(tmp / "depth.txt") << "not-a-number depth/x.png\n";
  EXPECT_FALSE(TumDataset::open(tmp.string(), TumDatasetOptions{}, &err));
  EXPECT_NE(err.find("timestamp"), std::string::npos);
  TumDatasetOptions bad;
  bad.rate_divisor = 0;
  EXPECT_FALSE(TumDataset::open(kExcerpt, bad, &err));
  std::filesystem::remove_all(tmp);
}

TEST(TumDataset, AJpegColourImageIsDecodedAsTheGroundStationDecodesTheStream) {
  // GIVEN a folder whose colour image is a JPEG, as a replayed flight's are
  std::string err;
  auto src = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(src) << err;
  auto frame = src->load(0, &err);
  ASSERT_TRUE(frame) << err;
  const auto tmp = std::filesystem::temp_directory_path() /
                   ("slam_dataset_test_jpeg_" + std::to_string(::getpid()));
  std::filesystem::create_directories(tmp / "rgb");
  std::filesystem::create_directories(tmp / "depth");
  cv::Mat rgb;
  cv::cvtColor(frame->rgb, rgb, cv::COLOR_BGR2RGB);
  encodings::JpegEncoder encoder(80);
  const auto jpeg = encoder.encode(rgb.data, rgb.cols, rgb.rows, &err);
  ASSERT_TRUE(jpeg) << err;
  std::ofstream(tmp / "rgb" / "1.jpg", std::ios::binary)
      .write(reinterpret_cast<const char*>(jpeg->data()),
             static_cast<std::streamsize>(jpeg->size()));
  ASSERT_TRUE(cv::imwrite((tmp / "depth" / "1.png").string(), frame->depth));
  std::ofstream(tmp / "rgb.txt") << "1.000000 rgb/1.jpg\n";
  std::ofstream(tmp / "depth.txt") << "1.000000 depth/1.png\n";
  // WHEN it is loaded
  auto ds = TumDataset::open(tmp.string(), TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  auto loaded = ds->load(0, &err);
  ASSERT_TRUE(loaded) << err;
  // THEN its pixels are the ground station's decoder's (TurboJPEG, fast IDCT), in BGR, and not
  // OpenCV's (the accurate IDCT), which would give SLAM other pixels than it had in flight
  encodings::JpegDecoder decoder;
  const auto decoded = decoder.decode(jpeg->data(), jpeg->size(), rgb.cols, rgb.rows, &err);
  ASSERT_TRUE(decoded) << err;
  cv::Mat expected;
  cv::cvtColor(cv::Mat(rgb.rows, rgb.cols, CV_8UC3, const_cast<std::uint8_t*>(decoded->data())),
               expected, cv::COLOR_RGB2BGR);
  EXPECT_EQ(cv::norm(loaded->rgb, expected, cv::NORM_INF), 0.0);
  const cv::Mat opencv = cv::imread((tmp / "rgb" / "1.jpg").string(), cv::IMREAD_COLOR);
  EXPECT_GT(cv::norm(opencv, expected, cv::NORM_INF), 0.0);
  std::filesystem::remove_all(tmp);
}

}  // namespace
}  // namespace rgbdquad::slam
