// MapCheckpointer with data time passed in: a map change is written once the period has passed
// since the last write whether or not another keyframe comes (the hover after a waypoint), an
// unchanged map is never rewritten, a loop correction is written at once, and a change made
// while a write is on its way stays pending. Each test writes into its own temporary file and
// reads it back with load_map; no threads, no clock.
#include "slam/pipeline/map_checkpointer.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "slam/map/map_io.hpp"

namespace rgbdquad::slam {
namespace {

constexpr double kPeriodS = 1.0;  // PipelineOptions::checkpoint_period_s's default
constexpr double kFrameS = 1.0 / 30.0;
constexpr double kStampTolS = 1e-9;

MapFileContext context() {
  MapFileContext c;
  c.features.kind = DetectorKind::kOrb;
  return c;
}

class MapCheckpointerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = (std::filesystem::path(::testing::TempDir()) /
             (std::string("checkpoint_") + info->name() + ".map"))
                .string();
    std::filesystem::remove(path_);
    cp_ = std::make_unique<MapCheckpointer>(path_, kPeriodS, map_, context());
  }
  void TearDown() override { std::filesystem::remove(path_); }

  /// Adds keyframe `id` made at data time `stamp_s` (what tracking and mapping do to the map).
  void add_keyframe(std::int64_t id, double stamp_s) {
    MapKeyframe kf;
    kf.id = id;
    kf.stamp_s = stamp_s;
    kf.features.features = std::make_shared<const FrameFeatures>();
    std::lock_guard<MapMutex> lock(map_->mutex);
    map_->map.add_keyframe(std::move(kf));
  }
  /// A loop correction moved the map.
  void correct() {
    std::lock_guard<MapMutex> lock(map_->mutex);
    ++map_->corrections;
  }
  /// The mapping (or loop-closing) thread's call after a keyframe, writing what falls due at once.
  void mapped() {
    if (const std::optional<double> now_s = cp_->map_changed()) cp_->write(*now_s);
  }
  /// Frames every 1/30 s from `from_s` to `to_s`: the per-frame check, writing what falls due.
  /// Returns the data time of each write.
  std::vector<double> frames(double from_s, double to_s) {
    std::vector<double> writes;
    for (int i = 0; from_s + i * kFrameS <= to_s + kStampTolS; ++i) {
      const double t = from_s + i * kFrameS;
      if (cp_->take_due(t)) {
        cp_->write(t);
        writes.push_back(t);
      }
    }
    return writes;
  }
  /// Keyframe ids in the checkpoint file; its correction count into `corrections`.
  std::vector<std::int64_t> written_keyframes(std::uint64_t* corrections = nullptr) const {
    std::string error;
    const auto map = load_map(path_, context(), &error, corrections);
    EXPECT_TRUE(map) << error;
    std::vector<std::int64_t> ids;
    if (map)
      for (const auto& [id, kf] : map->keyframes()) ids.push_back(id);
    return ids;
  }

  std::string path_;
  std::shared_ptr<SharedMap> map_ = std::make_shared<SharedMap>();
  std::unique_ptr<MapCheckpointer> cp_;
};

TEST_F(MapCheckpointerTest,
       GivenAKeyframeJustAfterACheckpointAndAHoverThenItIsWrittenAPeriodLater) {
  // GIVEN the first keyframe at 10.0 s, checkpointed at once
  add_keyframe(0, 10.0);
  mapped();
  ASSERT_EQ(cp_->stats().written, 1u);
  // WHEN a keyframe is made 0.2 s later (the craft arrives at its waypoint) and then none (hover)
  add_keyframe(6, 10.2);
  mapped();
  EXPECT_EQ(cp_->stats().written, 1u) << "not due yet: 0.2 s of the 1 s period";
  EXPECT_TRUE(cp_->pending());
  const std::vector<double> writes = frames(10.2 + kFrameS, 14.0);
  // THEN the first frame at which the period has passed writes it, once, with both keyframes
  ASSERT_EQ(writes.size(), 1u);
  EXPECT_GE(writes[0], 11.0 - kStampTolS);
  EXPECT_LT(writes[0], 11.0 + kFrameS);
  EXPECT_EQ(cp_->stats().written, 2u);
  EXPECT_FALSE(cp_->pending());
  EXPECT_EQ(written_keyframes(), (std::vector<std::int64_t>{0, 6}));
}

TEST_F(MapCheckpointerTest, GivenNoChangeSinceTheLastWriteThenNothingIsWrittenHoweverLongItHovers) {
  // GIVEN a map checkpointed at 10.0 s
  add_keyframe(0, 10.0);
  mapped();
  ASSERT_EQ(cp_->stats().written, 1u);
  const auto before = std::filesystem::last_write_time(path_);
  // WHEN a minute of frames passes without a change
  const std::vector<double> writes = frames(10.0 + kFrameS, 70.0);
  // THEN nothing is written
  EXPECT_TRUE(writes.empty());
  EXPECT_EQ(cp_->stats().written, 1u);
  EXPECT_EQ(std::filesystem::last_write_time(path_), before);
}

TEST_F(MapCheckpointerTest, GivenSteadyKeyframesThenTheMapIsWrittenOncePerPeriodWithinAFrame) {
  // GIVEN the first keyframe, checkpointed at once (nothing to wait for)
  add_keyframe(0, 10.0);
  std::vector<double> writes;
  if (const std::optional<double> now_s = cp_->map_changed()) {
    cp_->write(*now_s);
    writes.push_back(*now_s);
  }
  ASSERT_EQ(writes.size(), 1u);
  // WHEN keyframes come every 0.3 s for 3 s, frames every 1/30 s between them, then 1 s of hover
  for (int k = 1; k <= 10; ++k) {
    const double t = 10.0 + 0.3 * k;
    add_keyframe(k, t);
    if (const std::optional<double> now_s = cp_->map_changed()) {
      cp_->write(*now_s);
      writes.push_back(*now_s);
    }
    for (double w : frames(t + kFrameS, t + 0.3 - kFrameS / 2)) writes.push_back(w);
  }
  for (double w : frames(13.0 + kFrameS, 14.0)) writes.push_back(w);
  // THEN the map is written once per period (10, ~11, ~12, ~13 s), each write within a frame of
  // falling due, and the last keyframe is in the file
  ASSERT_EQ(writes.size(), 4u);
  for (std::size_t i = 1; i < writes.size(); ++i) {
    EXPECT_GE(writes[i] - writes[i - 1], kPeriodS - kStampTolS);
    EXPECT_LT(writes[i] - writes[i - 1], kPeriodS + kFrameS + kStampTolS);
  }
  EXPECT_FALSE(cp_->pending());
  EXPECT_EQ(written_keyframes().back(), 10);
}

TEST_F(MapCheckpointerTest, GivenALoopCorrectionThenItIsWrittenAtOnce) {
  // GIVEN a map checkpointed at 10.0 s
  add_keyframe(0, 10.0);
  mapped();
  ASSERT_EQ(cp_->stats().written, 1u);
  // WHEN a keyframe 0.2 s later closes a loop that moves the map
  add_keyframe(6, 10.2);
  correct();
  mapped();
  // THEN the corrected map is written at once, with its correction count
  EXPECT_EQ(cp_->stats().written, 2u);
  std::uint64_t corrections = 0;
  EXPECT_EQ(written_keyframes(&corrections), (std::vector<std::int64_t>{0, 6}));
  EXPECT_EQ(corrections, 1u);
  EXPECT_FALSE(cp_->pending());
}

TEST_F(MapCheckpointerTest, GivenAChangeWhileAWriteIsOnItsWayThenItStaysPending) {
  // GIVEN a pending change whose write a frame claimed
  add_keyframe(0, 10.0);
  mapped();
  add_keyframe(6, 10.2);
  mapped();
  ASSERT_TRUE(cp_->take_due(11.0));
  EXPECT_FALSE(cp_->take_due(11.0 + kFrameS)) << "one claim per due checkpoint";
  // WHEN the write runs with the claim (it copies the map then) and a keyframe is mapped after it
  cp_->write(11.0);
  add_keyframe(9, 11.1);
  mapped();
  // THEN the later keyframe is pending and written a period after the write
  EXPECT_TRUE(cp_->pending());
  EXPECT_TRUE(frames(11.1 + kFrameS, 11.9).empty());
  EXPECT_EQ(frames(11.9 + kFrameS, 12.5).size(), 1u);
  EXPECT_EQ(written_keyframes(), (std::vector<std::int64_t>{0, 6, 9}));
}

TEST_F(MapCheckpointerTest, GivenDataTimeThatWentBackThenAPendingCheckpointIsNotHeldOff) {
  // GIVEN a checkpoint at 100 s and a later change
  add_keyframe(0, 100.0);
  mapped();
  add_keyframe(1, 100.2);
  mapped();
  // WHEN the frames' clock restarts near 0 (a client restarted with the same map id)
  // THEN the pending change is written at the next frame, not 100 s later
  EXPECT_EQ(frames(0.5, 0.6).size(), 1u);
  EXPECT_EQ(cp_->stats().written, 2u);
}

TEST(MapCheckpointer, GivenNoPathThenNothingIsEverDue) {
  auto map = std::make_shared<SharedMap>();
  MapCheckpointer cp("", kPeriodS, map, context());
  MapKeyframe kf;
  kf.features.features = std::make_shared<const FrameFeatures>();
  map->map.add_keyframe(std::move(kf));
  EXPECT_FALSE(cp.map_changed().has_value());
  EXPECT_FALSE(cp.take_due(1e9));
  cp.write_forced();
  EXPECT_EQ(cp.stats().written, 0u);
}

}  // namespace
}  // namespace rgbdquad::slam
