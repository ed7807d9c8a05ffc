// Frame validation: table of good, blank, malformed and out-of-order frames.
#include "rgbdquad/capture/frame_validator.h"

#include <gtest/gtest.h>

namespace rgbdquad::capture {
namespace {

RgbFrame rgb(std::int64_t t_us, std::uint8_t fill, int w = 640, int h = 480) {
  RgbFrame f;
  f.capture_timestamp_us = t_us;
  f.width = w;
  f.height = h;
  f.rgb.assign(static_cast<std::size_t>(w) * h * 3, fill);
  return f;
}
DepthFrame depth(std::int64_t t_us, std::uint16_t fill, int w = 640, int h = 480) {
  DepthFrame f;
  f.capture_timestamp_us = t_us;
  f.width = w;
  f.height = h;
  f.depth.assign(static_cast<std::size_t>(w) * h, fill);
  return f;
}

TEST(FrameValidator, ClassifiesTableOfFrames) {
  struct Case {
    const char* name;
    SourceFrame frame;
    Verdict expected;
  };
  auto one_pixel_lit = rgb(50, 0);
  one_pixel_lit.rgb[12345] = 1;
  auto one_depth_reading = depth(60, 0);
  one_depth_reading.depth[777] = 900;
  auto short_rgb = rgb(70, 10);
  short_rgb.rgb.pop_back();
  auto bad_units = depth(80, 1000);
  bad_units.units_per_m = 0;
  std::vector<Case> cases;
  cases.push_back({"good rgb", rgb(10, 90), Verdict::kOk});
  cases.push_back({"good depth", depth(10, 1500), Verdict::kOk});
  cases.push_back({"all-black rgb", rgb(20, 0), Verdict::kBlank});
  cases.push_back({"all-zero depth", depth(20, 0), Verdict::kBlank});
  cases.push_back({"rgb with one lit byte", one_pixel_lit, Verdict::kOk});
  cases.push_back({"depth with one reading", one_depth_reading, Verdict::kOk});
  cases.push_back({"wrong rgb size", rgb(90, 10, 320, 240), Verdict::kMalformed});
  cases.push_back({"short rgb buffer", short_rgb, Verdict::kMalformed});
  cases.push_back({"zero depth units", bad_units, Verdict::kMalformed});
  cases.push_back({"rgb timestamp back in time", rgb(40, 10), Verdict::kOutOfOrder});
  cases.push_back({"depth timestamp repeated", depth(60, 10), Verdict::kOutOfOrder});

  FrameValidator validator({});
  for (const auto& c : cases) {
    EXPECT_EQ(validator.check(c.frame), c.expected) << c.name;
  }
  const auto n = validator.counters();
  EXPECT_EQ(n.rgb_ok, 2u);
  EXPECT_EQ(n.depth_ok, 2u);
  EXPECT_EQ(n.rgb_blank, 1u);
  EXPECT_EQ(n.depth_blank, 1u);
  EXPECT_EQ(n.malformed, 3u);
  EXPECT_EQ(n.out_of_order, 2u);
  EXPECT_EQ(n.dropped(), 7u);
}

TEST(FrameValidator, BlackLevelThreshold) {
  FrameValidatorOptions options;
  options.rgb_black_level = 3;
  FrameValidator validator(options);
  EXPECT_EQ(validator.check(rgb(1, 3)), Verdict::kBlank);
  EXPECT_EQ(validator.check(rgb(2, 4)), Verdict::kOk);
  std::string error;
  options.rgb_black_level = 300;
  EXPECT_FALSE(options.is_valid(&error));
}

}  // namespace
}  // namespace rgbdquad::capture
