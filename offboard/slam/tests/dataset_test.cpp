// Dataset reader: association within 20 ms, rate reduction, clear errors for bad folders.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

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

}  // namespace
}  // namespace rgbdquad::slam
