// The ground station's pure parts, without sockets or threads, time passed in: the track kept for
// the dashboard (TrajectoryTrail) and the stream figures (StreamStats). GIVEN/WHEN/THEN.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <vector>

#include "core/stream_stats.hpp"
#include "core/trajectory_trail.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr std::int64_t kFramePeriodUs = 33'333;  // 30 fps

TEST(TrajectoryTrail, GivenFewerPointsThanShownWhenDecimatedThenEveryPointComesBackInOrder) {
  TrajectoryTrail trail(5000);
  for (int i = 0; i < 10; ++i) trail.add(i, -i);
  const auto shown = trail.decimated();
  ASSERT_EQ(shown.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(shown[i], (std::array<double, 2>{double(i), double(-i)}));
}

TEST(TrajectoryTrail, GivenAFullTrailWhenAPointIsAddedThenTheOldestIsDropped) {
  TrajectoryTrail trail(3);
  for (int i = 0; i < 4; ++i) trail.add(i, 0.0);
  EXPECT_EQ(trail.size(), 3u);
  const auto shown = trail.decimated();
  ASSERT_EQ(shown.size(), 3u);
  EXPECT_EQ(shown.front()[0], 1.0);
  EXPECT_EQ(shown.back()[0], 3.0);
}

TEST(TrajectoryTrail, GivenManyPointsWhenDecimatedThenEveryNthFromTheOldestIsShown) {
  struct Row {
    int points;
    std::size_t shown;
  };
  // stride = size / 500: 1000 -> every 2nd (500), 1499 -> every 2nd (750), 5000 -> every 10th.
  for (const Row row : {Row{500, 500}, Row{1000, 500}, Row{1499, 750}, Row{5000, 500}}) {
    TrajectoryTrail trail(5000);
    for (int i = 0; i < row.points; ++i) trail.add(i, 0.0);
    const auto shown = trail.decimated();
    EXPECT_EQ(shown.size(), row.shown) << row.points;
    EXPECT_EQ(shown.front()[0], 0.0);
  }
}

TEST(StreamStats, GivenNoFrameWhenAskedThenEverythingIsZeroAndNoError) {
  const StreamStats stats;
  EXPECT_EQ(stats.frames(), 0);
  EXPECT_EQ(stats.fps(), 0.0);
  EXPECT_EQ(stats.latency_ms(), 0.0);
  EXPECT_TRUE(stats.error().empty());
}

TEST(StreamStats, GivenTwoFramesWhenTheSecondArrivesThenTheRateIsTheInstantOne) {
  StreamStats stats;
  stats.on_frame(1'000'000, 3.0);
  EXPECT_EQ(stats.fps(), 0.0);  // one frame: no rate yet
  stats.on_frame(1'000'000 + 50'000, 4.5);
  EXPECT_DOUBLE_EQ(stats.fps(), 20.0);
  EXPECT_EQ(stats.frames(), 2);
  EXPECT_EQ(stats.latency_ms(), 4.5);
}

TEST(StreamStats, GivenASteadyRateWhenTheRateChangesThenTheAverageMovesByOneFifthPerFrame) {
  StreamStats stats;
  std::int64_t t = 1'000'000;
  for (int i = 0; i < 3; ++i) stats.on_frame(t += kFramePeriodUs, 1.0);
  const double before = stats.fps();
  stats.on_frame(t += 100'000, 1.0);  // 10 fps
  EXPECT_DOUBLE_EQ(stats.fps(), 0.8 * before + 0.2 * 10.0);
}

TEST(StreamStats, GivenAFrameNotLaterThanThePreviousWhenCountedThenTheRateIsKept) {
  StreamStats stats;
  stats.on_frame(1'000'000, 1.0);
  stats.on_frame(1'050'000, 1.0);
  const double fps = stats.fps();
  stats.on_frame(1'050'000, 1.0);
  EXPECT_EQ(stats.fps(), fps);
  EXPECT_EQ(stats.frames(), 3);
}

TEST(StreamStats, GivenASourceErrorWhenSetThenItIsShownUntilReplaced) {
  StreamStats stats;
  stats.set_error("replay finished");
  EXPECT_EQ(stats.error(), "replay finished");
  stats.set_error("");
  EXPECT_TRUE(stats.error().empty());
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
