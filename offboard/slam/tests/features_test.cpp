// Feature stage: where ORB keypoints of the coarse pyramid levels land in the input image.
#include "slam/features/features.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

namespace rgbdquad::slam {
namespace {

/// A camera for the tests' images: it only lifts points to 3D here, any valid one will do.
Intrinsics test_camera(const cv::Mat& rgb) {
  Intrinsics k;
  k.fx_px = k.fy_px = 500;
  k.cx_px = rgb.cols / 2.0;
  k.cy_px = rgb.rows / 2.0;
  k.depth_units_per_m = 5000;
  return k;
}

/// ORB features of `rgb` with `depth` (raw units of test_camera; empty: a wall at 1 m).
FrameFeatures orb_features(const cv::Mat& rgb, bool pixel_centres, cv::Mat depth = {}) {
  FeatureOptions o;
  o.kind = DetectorKind::kOrb;
  o.undistort = false;
  o.orb_pixel_centres = pixel_centres;
  std::string err;
  auto extractor = FeatureExtractor::create(o, test_camera(rgb), &err);
  EXPECT_TRUE(extractor) << err;
  RgbdFrame f;
  f.rgb = rgb;
  f.depth = depth.empty() ? cv::Mat(rgb.rows, rgb.cols, CV_16UC1, cv::Scalar(5000)) : depth;
  auto out = extractor->extract(f, &err);
  EXPECT_TRUE(out) << err;
  return out ? *out : FrameFeatures{};
}

struct LevelAgreement {
  int pairs = 0;
  double max_offset_px = 0;  ///< |input keypoint - (2 x half-size keypoint + 0.5)|, either axis
};

/// Keypoints of pyramid level L + 1 of the input that are the same corner as a keypoint of level L
/// of the half-size copy (bit-identical descriptor: same level image, same place).
LevelAgreement compare(const FrameFeatures& full, const FrameFeatures& half) {
  LevelAgreement a;
  for (std::size_t i = 0; i < full.keypoints.size(); ++i) {
    if (full.keypoints[i].octave < 1) continue;
    for (std::size_t j = 0; j < half.keypoints.size(); ++j) {
      if (half.keypoints[j].octave != full.keypoints[i].octave - 1) continue;
      if (cv::norm(full.descriptors.row(static_cast<int>(i)),
                   half.descriptors.row(static_cast<int>(j)), cv::NORM_HAMMING) != 0)
        continue;
      // Pixel centres of the copy in input pixels: its pixel p covers input 2p .. 2p + 1.
      const double dx = full.keypoints[i].pt.x - (2.0 * half.keypoints[j].pt.x + 0.5);
      const double dy = full.keypoints[i].pt.y - (2.0 * half.keypoints[j].pt.y + 0.5);
      a.max_offset_px = std::max({a.max_offset_px, std::fabs(dx), std::fabs(dy)});
      ++a.pairs;
      break;
    }
  }
  return a;
}

TEST(OrbKeypoints, ACornerOnACoarseLevelLandsOnTheInputPixelItWasFoundAt) {
  // GIVEN a real photograph and a half-size copy made as cv::ORB makes its pyramid levels, so
  // that level L + 1 of the photograph is level L of the copy
  const cv::Mat full = cv::imread(std::string(SLAM_REPO_DIR) +
                                  "/tests/data/fr1_xyz_first30/rgb/1305031102.175304.png");
  ASSERT_FALSE(full.empty());
  cv::Mat half;
  cv::resize(full, half, cv::Size(full.cols / 2, full.rows / 2), 0, 0, cv::INTER_LINEAR_EXACT);
  // WHEN ORB keypoints are taken from both, with and without FeatureOptions::orb_pixel_centres
  const LevelAgreement centred = compare(orb_features(full, true), orb_features(half, true));
  const LevelAgreement as_reported = compare(orb_features(full, false), orb_features(half, false));
  // THEN with it, a corner found on a shared level lands on the same input pixel from both
  ASSERT_GE(centred.pairs, 20);
  EXPECT_LT(centred.max_offset_px, 1e-3);
  // AND as cv::ORB reports them the two disagree by the half pixel the correction restores
  ASSERT_GE(as_reported.pairs, 20);
  EXPECT_NEAR(as_reported.max_offset_px, 0.5, 1e-3);
}

TEST(SpreadKeypoints, CornersCrowdedIntoOnePatchLeaveRoomForEveryOtherCell) {
  // GIVEN 200 strong level-0 corners crowded into one 30 px cell and one weaker corner in each of
  // 40 other cells
  std::vector<cv::KeyPoint> candidates;
  for (int i = 0; i < 200; ++i)
    candidates.emplace_back(cv::Point2f(5.0f + 0.1f * i, 5.0f), 7.0f, 0.0f, 100.0f + i, 0);
  for (int c = 1; c <= 40; ++c)
    candidates.emplace_back(cv::Point2f(30.0f * c + 15.0f, 200.0f), 7.0f, 0.0f, 1.0f, 0);
  // WHEN 60 are kept
  const std::vector<std::size_t> kept = spread_keypoints(candidates, 60, 2.0, 30.0);
  // THEN every other cell keeps its corner and the crowded cell gets the rest, strongest first
  ASSERT_EQ(kept.size(), 60u);
  int crowded = 0;
  float weakest_crowded = 1e9f;
  for (std::size_t i : kept)
    if (candidates[i].pt.y < 30.0f) {
      ++crowded;
      weakest_crowded = std::min(weakest_crowded, candidates[i].response);
    }
  EXPECT_EQ(crowded, 20);
  EXPECT_EQ(weakest_crowded, 100.0f + 180);
}

TEST(SpreadKeypoints, EachPyramidLevelKeepsItsShareAndFewCandidatesAreAllKept) {
  // GIVEN 300 corners on level 0 and 100 on level 1, spread evenly
  std::vector<cv::KeyPoint> candidates;
  for (int i = 0; i < 300; ++i)
    candidates.emplace_back(cv::Point2f(2.0f * i, 10.0f), 7.0f, 0.0f, 1.0f + i, 0);
  for (int i = 0; i < 100; ++i)
    candidates.emplace_back(cv::Point2f(6.0f * i, 300.0f), 14.0f, 0.0f, 1.0f + i, 1);
  // WHEN a quarter are kept
  const std::vector<std::size_t> kept = spread_keypoints(candidates, 100, 2.0, 30.0);
  // THEN each level keeps a quarter of its own corners
  int level1 = 0;
  for (std::size_t i : kept) level1 += candidates[i].octave == 1 ? 1 : 0;
  EXPECT_EQ(kept.size(), 100u);
  EXPECT_EQ(level1, 25);
  // AND asking for more than there are keeps every candidate
  EXPECT_EQ(spread_keypoints(candidates, 1000, 2.0, 30.0).size(), candidates.size());
}

TEST(DepthFilter, KeypointsWithoutADepthReadingAreKeptApartAsBearings) {
  // GIVEN a real photograph whose depth image has no reading on its top half and a wall at 1 m
  // on its bottom half
  const cv::Mat rgb = cv::imread(std::string(SLAM_REPO_DIR) +
                                 "/tests/data/fr1_xyz_first30/rgb/1305031102.175304.png");
  ASSERT_FALSE(rgb.empty());
  cv::Mat depth(rgb.rows, rgb.cols, CV_16UC1, cv::Scalar(5000));
  depth.rowRange(0, rgb.rows / 2).setTo(0);
  // WHEN features are extracted
  const FrameFeatures out = orb_features(rgb, true, depth);
  const Intrinsics k = test_camera(rgb);
  // THEN those on the bottom half have depth, and every one on the top half is a depthless
  // feature: its descriptor, and its bearing at z = 1 through its pixel
  ASSERT_TRUE(out.depthless);
  const FrameFeatures& d = *out.depthless;
  ASSERT_GE(d.keypoints.size(), 20u);
  ASSERT_GE(out.keypoints.size(), 20u);
  EXPECT_EQ(out.keypoints.size() + d.keypoints.size(), out.detected);
  EXPECT_EQ(d.descriptors.rows, static_cast<int>(d.keypoints.size()));
  ASSERT_EQ(d.points_cam_m.size(), d.keypoints.size());
  for (const cv::KeyPoint& kp : out.keypoints) EXPECT_GE(std::lround(kp.pt.y), rgb.rows / 2);
  for (std::size_t i = 0; i < d.keypoints.size(); ++i) {
    EXPECT_LT(std::lround(d.keypoints[i].pt.y), rgb.rows / 2);
    EXPECT_DOUBLE_EQ(d.points_cam_m[i].z(), 1.0);
    EXPECT_NEAR(d.points_cam_m[i].x() * k.fx_px + k.cx_px, d.keypoints[i].pt.x, 1e-3);
  }
}

}  // namespace
}  // namespace rgbdquad::slam
