// Feature stage: where ORB keypoints of the coarse pyramid levels land in the input image.
#include "slam/features/features.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

namespace rgbdquad::slam {
namespace {

FrameFeatures orb_features(const cv::Mat& rgb, bool pixel_centres) {
  FeatureOptions o;
  o.kind = DetectorKind::kOrb;
  o.undistort = false;
  o.orb_pixel_centres = pixel_centres;
  Intrinsics k;  // only lifts points to 3D here: any valid camera will do
  k.fx_px = k.fy_px = 500;
  k.cx_px = rgb.cols / 2.0;
  k.cy_px = rgb.rows / 2.0;
  k.depth_units_per_m = 5000;
  std::string err;
  auto extractor = FeatureExtractor::create(o, k, &err);
  EXPECT_TRUE(extractor) << err;
  RgbdFrame f;
  f.rgb = rgb;
  f.depth = cv::Mat(rgb.rows, rgb.cols, CV_16UC1, cv::Scalar(5000));  // a wall at 1 m
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

}  // namespace
}  // namespace rgbdquad::slam
