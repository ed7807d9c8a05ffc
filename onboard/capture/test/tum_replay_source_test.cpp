// TUM replay on the shipped excerpt, on a simulated clock: order, timestamps, pacing, loop.
#include "rgbdquad/capture/tum_replay_source.h"

#include <gtest/gtest.h>

namespace rgbdquad::capture {
namespace {

constexpr const char* kDesk = RGBD_TEST_DATA_DIR "/fr1_desk_9frames";

TEST(TumReplaySource, DeliversEveryFrameInTimeOrderWithDatasetTimestamps) {
  ManualClock clock(1'000'000);
  TumReplayOptions options;
  options.directory = kDesk;
  options.fps = -1;  // unpaced
  TumReplaySource source(options, &clock);
  ASSERT_EQ(source.rgb_count(), 9u);
  ASSERT_EQ(source.depth_count(), 9u);
  std::int64_t previous = 0;
  int rgb = 0, depth = 0;
  while (auto frame = source.next()) {
    const std::int64_t t = std::visit([](const auto& f) { return f.capture_timestamp_us; }, *frame);
    EXPECT_GE(t, previous);
    previous = t;
    if (auto* d = std::get_if<DepthFrame>(&*frame)) {
      if (depth == 0) {
        EXPECT_EQ(t, 1305031453374112);  // first line of depth.txt
      }
      EXPECT_EQ(d->units_per_m, kTumDepthUnitsPerM);
      EXPECT_TRUE(d->registered_to_rgb);
      EXPECT_EQ(d->depth.size(), 640u * 480u);
      ++depth;
    } else {
      const auto& r = std::get<RgbFrame>(*frame);
      EXPECT_EQ(r.rgb.size(), 640u * 480u * 3u);
      ++rgb;
    }
  }
  EXPECT_EQ(rgb, 9);
  EXPECT_EQ(depth, 9);
  EXPECT_TRUE(source.error().empty());
  EXPECT_EQ(clock.now_us(), 1'000'000) << "unpaced replay must not wait";
}

TEST(TumReplaySource, OriginalTimingWaitsForTheDatasetSpan) {
  ManualClock clock(0);
  TumReplayOptions options;
  options.directory = kDesk;
  TumReplaySource source(options, &clock);
  while (source.next()) {
  }
  // first entry 1305031453.359684 (rgb), last 1305031453.636951 (depth): 277.267 ms
  EXPECT_EQ(clock.now_us(), 277267);
}

TEST(TumReplaySource, FixedRateScalesTimeAndLoopKeepsTimestampsIncreasing) {
  ManualClock clock(0);
  TumReplayOptions options;
  options.directory = kDesk;
  options.fps = 10;  // RGB every 100 ms instead of the recorded ~33.5 ms
  options.loop = true;
  options.max_frames = 36;  // two passes
  TumReplaySource source(options, &clock);
  std::int64_t previous = 0;
  std::vector<std::int64_t> rgb_wall_us;
  for (int i = 0; i < 36; ++i) {
    auto frame = source.next();
    ASSERT_TRUE(frame.has_value());
    const std::int64_t t = std::visit([](const auto& f) { return f.capture_timestamp_us; }, *frame);
    EXPECT_GT(t, previous - 1);
    previous = t;
    if (std::holds_alternative<RgbFrame>(*frame)) rgb_wall_us.push_back(clock.now_us());
  }
  EXPECT_FALSE(source.next().has_value()) << "max_frames reached";
  ASSERT_EQ(rgb_wall_us.size(), 18u);
  // 8 RGB periods in the first pass at 10 fps = 800 ms
  EXPECT_NEAR(static_cast<double>(rgb_wall_us[8] - rgb_wall_us[0]), 800000.0, 1.0);
}

TEST(TumReplaySource, MissingFolderThrowsClearError) {
  ManualClock clock;
  TumReplayOptions options;
  options.directory = "/nonexistent/tum";
  try {
    TumReplaySource source(options, &clock);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/tum/rgb.txt"), std::string::npos);
  }
}

}  // namespace
}  // namespace rgbdquad::capture
