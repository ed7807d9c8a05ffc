// Kinect v1 11-bit disparity -> millimetres: the per-frame table is the conversion itself.
#include <gtest/gtest.h>

#include "rgbdquad/capture/freenect_source.h"

namespace rgbdquad::capture {
namespace {

TEST(FreenectDisparity, GivenEveryElevenBitValueThenTheTableHoldsTheConversionsResult) {
  const FreenectSource::DisparityTable table = FreenectSource::disparity_to_mm_table();
  for (std::uint16_t raw = 0; raw < table.size(); ++raw)
    ASSERT_EQ(table[raw], FreenectSource::disparity_to_mm(raw)) << raw;
}

TEST(FreenectDisparity, GivenKnownRawValuesThenDepthsFollowMagnenatsFit) {
  // 2047 is the sensor's "no reading"; raw 0 is the nearest the fit gives (0.1236 tan(1.1863) m).
  EXPECT_EQ(FreenectSource::disparity_to_mm(2047), 0);
  EXPECT_EQ(FreenectSource::disparity_to_mm(0), 305);
  // raw 800: 0.1236 * tan(800 / 2842.5 + 1.1863) = 1.195 m
  EXPECT_EQ(FreenectSource::disparity_to_mm(800), 1195);
  // beyond ~1084 the tangent passes pi/2: not a measurable depth
  EXPECT_EQ(FreenectSource::disparity_to_mm(1100), 0);
}

}  // namespace
}  // namespace rgbdquad::capture
