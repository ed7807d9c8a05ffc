// TUM replay on the shipped excerpt, on a simulated clock: order, timestamps, pacing, loop.
#include "rgbdquad/capture/tum_replay_source.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

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
      EXPECT_FALSE(r.accel) << "the excerpt has no accelerometer.txt";
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

// The shipped excerpt's lists and images plus an accelerometer.txt of our own, in a folder unique
// per process (parallel runs never share it).
class TumAccelFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    namespace fs = std::filesystem;
    dir_ = fs::temp_directory_path() / ("tum_accel_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    for (const char* name : {"rgb.txt", "depth.txt"})
      fs::copy_file(fs::path(kDesk) / name, dir_ / name, fs::copy_options::overwrite_existing);
    for (const char* name : {"rgb", "depth"})
      fs::create_directory_symlink(fs::path(kDesk) / name, dir_ / name);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(TumAccelFolder, GivenAccelerometerTxtThenEachRgbFrameCarriesTheNearestReading) {
  // GIVEN readings 2 ms before and 10 ms after the first colour stamp (1305031453.359684)
  std::ofstream(dir_ / "accelerometer.txt") << "# accelerometer data\n# timestamp ax ay az\n"
                                            << "1305031453.369684 0.5 8.0 -4.0\n"
                                            << "1305031453.357684 -0.1 9.0 -3.0\n";
  ManualClock clock;
  TumReplayOptions options;
  options.directory = dir_.string();
  options.fps = -1;
  options.loop = true;
  TumReplaySource source(options, &clock);
  EXPECT_EQ(source.accel_count(), 2u);
  // WHEN the first loop and the first frame of the second are replayed
  std::vector<RgbFrame> rgb;
  while (rgb.size() < 10) {
    auto frame = source.next();
    ASSERT_TRUE(frame);
    if (auto* r = std::get_if<RgbFrame>(&*frame)) rgb.push_back(std::move(*r));
    if (auto* d = std::get_if<DepthFrame>(&*frame)) {
      EXPECT_EQ(d->depth.size(), 640u * 480u);
    }
  }
  // THEN the first colour frame has the reading 2 ms before it, every frame has one (the nearest,
  // however far: the ground station judges staleness), and a loop shifts it with the image
  ASSERT_TRUE(rgb[0].accel);
  EXPECT_EQ(rgb[0].accel->capture_timestamp_us, 1305031453357684);
  EXPECT_DOUBLE_EQ(rgb[0].accel->f_mps2[1], 9.0);
  for (const RgbFrame& r : rgb) ASSERT_TRUE(r.accel);
  EXPECT_EQ(rgb[9].accel->capture_timestamp_us - rgb[9].capture_timestamp_us,
            rgb[0].accel->capture_timestamp_us - rgb[0].capture_timestamp_us);
}

TEST_F(TumAccelFolder, GivenMalformedAccelerometerLineThenClearError) {
  std::ofstream(dir_ / "accelerometer.txt") << "1305031452.80 0.5 eight -4.0\n";
  ManualClock clock;
  TumReplayOptions options;
  options.directory = dir_.string();
  try {
    TumReplaySource source(options, &clock);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("accelerometer.txt:1"), std::string::npos) << e.what();
  }
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
