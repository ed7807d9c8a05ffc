// Matching stage: Lowe's ratio test and NNMMT on crafted descriptors (float and binary).
#include "slam/matching/matching.hpp"

#include <gtest/gtest.h>

namespace rgbdquad::slam {
namespace {

cv::Mat rows(std::initializer_list<std::initializer_list<float>> r) {
  cv::Mat m(static_cast<int>(r.size()), static_cast<int>(r.begin()->size()), CV_32F);
  int i = 0;
  for (const auto& row : r) {
    int j = 0;
    for (float v : row) m.at<float>(i, j++) = v;
    ++i;
  }
  return m;
}

TEST(Matching, GivenAmbiguousSecondNeighbourWhenRatioTestThenRejected) {
  // train: A=(10,0), B=(0,10), C=(10,1)
  const cv::Mat train = rows({{10, 0}, {0, 10}, {10, 1}});
  // q0 close to B only: distance 1 vs ~14 -> kept. q1 between A and C: 0.5 vs 0.5 -> rejected.
  const cv::Mat query = rows({{0, 9}, {10, 0.5f}});
  MatchOptions o;
  o.use_nnmmt = false;
  const auto m = match_descriptors(query, train, o);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].query, 0);
  EXPECT_EQ(m[0].train, 1);
  o.use_ratio_test = false;
  EXPECT_EQ(match_descriptors(query, train, o).size(), 2u);
}

TEST(Matching, GivenPairFartherThanHalfTheNormWhenNnmmtThenRejected) {
  const cv::Mat train = rows({{10, 0}, {-100, -100}});
  // q0=(4,0): nearest A at 6 > 0.5*|q0|=2 -> NNMMT rejects, although the ratio test passes.
  // q1=(9,0): nearest A at 1 <= 4.5 -> kept.
  const cv::Mat query = rows({{4, 0}, {9, 0}});
  MatchOptions o;
  const auto m = match_descriptors(query, train, o);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].query, 1);
  o.use_nnmmt = false;
  EXPECT_EQ(match_descriptors(query, train, o).size(), 2u);
}

TEST(Matching, GivenBinaryDescriptorsThenHammingAndPopcountOrigin) {
  cv::Mat train = (cv::Mat_<std::uint8_t>(2, 2) << 0xFF, 0x00, 0x00, 0xFF);
  // q0 = 0xFE 0x00: 1 bit from t0, 15 from t1; popcount 7 -> 1 <= 3.5 kept.
  // q1 = 0x01 0x00: 7 bits from t0, 9 from t1: ratio 0.78 -> rejected.
  cv::Mat query = (cv::Mat_<std::uint8_t>(2, 2) << 0xFE, 0x00, 0x01, 0x00);
  EXPECT_DOUBLE_EQ(distance_to_origin(query.row(0)), 7.0);
  const auto m = match_descriptors(query, train, MatchOptions{});
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].query, 0);
  EXPECT_EQ(m[0].train, 0);
  EXPECT_FLOAT_EQ(m[0].distance, 1.0f);
}

TEST(Matching, GivenMismatchedOrEmptyInputThenNoMatchesNoCrash) {
  const cv::Mat f = rows({{1, 2}});
  const cv::Mat b = (cv::Mat_<std::uint8_t>(1, 2) << 1, 2);
  EXPECT_TRUE(match_descriptors(f, b, MatchOptions{}).empty());
  EXPECT_TRUE(match_descriptors(cv::Mat(), f, MatchOptions{}).empty());
  EXPECT_TRUE(match_descriptors(f, f, MatchOptions{}).empty());  // one train row: no ratio test
}

}  // namespace
}  // namespace rgbdquad::slam
