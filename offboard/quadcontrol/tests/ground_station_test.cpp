// GroundStation driven without sockets or threads: constructed without firmware and never started,
// fed frames, SLAM results, operator commands and control ticks by hand with the time passed in,
// and read back through /api/state. GIVEN/WHEN/THEN.
#include "app/ground_station.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <string>

#include "link/control_codec.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr std::int64_t kStartUs = 10'000'000;
constexpr std::int64_t kFramePeriodUs = 33'333;  // 30 fps
constexpr int kWidthPx = 64, kHeightPx = 48;

/// A source that is never read (the station is not started).
class IdleSource final : public FrameSource {
 public:
  std::optional<CameraFrame> next(const std::atomic<bool>&, std::string* error) override {
    *error = "not read";
    return std::nullopt;
  }
  std::string describe() const override { return "idle test source"; }
};

CameraFrame frame_at(std::int64_t sequence, std::int64_t received_us) {
  CameraFrame f;
  f.sequence = sequence;
  f.capture_us = received_us - 2000;
  f.received_us = received_us;
  f.link_latency_ms = 2.0;
  f.rgb = cv::Mat(kHeightPx, kWidthPx, CV_8UC3, cv::Scalar(40, 80, 120));
  f.depth = cv::Mat(kHeightPx, kWidthPx, CV_16UC1,
                    cv::Scalar(static_cast<int>(1.5 * f.intrinsics.depth_units_per_m)));
  return f;
}

SlamResult slam_result(const CameraFrame& f, bool tracking) {
  SlamResult r;
  r.frame_sequence = f.sequence;
  r.capture_us = f.capture_us;
  r.tracking = tracking;
  r.state = tracking ? "tracking" : "lost";
  r.inliers = tracking ? 120 : 0;
  return r;
}

/// The shipped defaults, but the floor searched in the first tracked frame only (the test frames
/// show a wall, no floor): the floor frame is then the mount angle's fallback at once.
GroundStationOptions options() {
  GroundStationOptions o;
  o.floor_search_frames = 1;
  return o;
}

class GroundStationTest : public ::testing::Test {
 protected:
  GroundStation station{options(), std::make_unique<IdleSource>(), std::nullopt,
                        generated_control_spec(), rgbd_control::Key{}};
};

TEST_F(GroundStationTest, GivenNoFrameWhenTheStateIsTakenThenItShowsTheSourceAndNothingYet) {
  const nlohmann::json j = station.state_json(kStartUs);
  EXPECT_EQ(j["state"], "disarmed");
  EXPECT_EQ(j["stream"]["source"], "idle test source");
  EXPECT_EQ(j["stream"]["frames"], 0);
  EXPECT_EQ(j["stream"]["sequence"], -1);
  EXPECT_EQ(j["slam"]["link"], "starting");
  EXPECT_EQ(j["slam"]["state"], "waiting");
  EXPECT_FALSE(j["firmware"]["enabled"]);
  EXPECT_TRUE(j["pose"].is_null());
  EXPECT_FALSE(station.rgb_jpeg());
}

TEST_F(GroundStationTest, GivenFramesWhenTheyArriveThenTheStreamFiguresAndImagesFollow) {
  for (int i = 1; i <= 3; ++i) {
    CameraFrame f = frame_at(i, kStartUs + i * kFramePeriodUs);
    station.on_frame(f);
  }
  const nlohmann::json j = station.state_json(kStartUs + 4 * kFramePeriodUs);
  EXPECT_EQ(j["stream"]["frames"], 3);
  EXPECT_EQ(j["stream"]["sequence"], 3);
  EXPECT_NEAR(j["stream"]["fps"].get<double>(), 30.0, 0.01);
  EXPECT_EQ(j["stream"]["latency_ms"], 2.0);
  EXPECT_TRUE(station.rgb_jpeg());
  EXPECT_TRUE(station.depth_png());
}

TEST_F(GroundStationTest, GivenTrackedResultsWhenAppliedThenTheTrackAndTheMapGrowLostOnesDoNot) {
  std::int64_t t = kStartUs;
  for (int i = 1; i <= 3; ++i) {
    CameraFrame f = frame_at(i, t += kFramePeriodUs);
    station.on_frame(f);
    station.apply_slam_result(t + 5000, slam_result(f, true), f);
  }
  const nlohmann::json tracked = station.state_json(t + 6000);
  EXPECT_EQ(tracked["slam"]["state"], "tracking");
  EXPECT_EQ(tracked["slam"]["inliers"], 120);
  EXPECT_EQ(tracked["map"]["revision"], 3);
  EXPECT_EQ(tracked["trajectory"].size(), 3u);
  EXPECT_FALSE(tracked["pose"].is_null());
  EXPECT_TRUE(tracked["floor"]["fallback"]);
  EXPECT_GT(tracked["map"]["cloud_points"].get<std::size_t>(), 0u);

  CameraFrame f = frame_at(4, t += kFramePeriodUs);
  station.on_frame(f);
  EXPECT_FALSE(station.apply_slam_result(t + 5000, slam_result(f, false), f));
  const nlohmann::json lost = station.state_json(t + 6000);
  EXPECT_EQ(lost["slam"]["state"], "lost");
  EXPECT_EQ(lost["map"]["revision"], 3);
  EXPECT_EQ(lost["trajectory"].size(), 3u);
}

TEST_F(GroundStationTest, GivenTheOperatorArmsWhenTheControlTicksThenTheArmingGestureIsCommanded) {
  EXPECT_EQ(station.command(kStartUs, OperatorCommand::kArm), "");
  station.control_step(kStartUs + 20'000);
  const nlohmann::json j = station.state_json(kStartUs + 20'000);
  EXPECT_EQ(j["state"], "armed");
  EXPECT_TRUE(j["command"]["armed"]);
  EXPECT_EQ(j["command"]["yaw_pct"], 100.0);  // yaw full right while the gesture lasts
  const auto pwm = station.command_at(kStartUs + 40'000, 1);
  ASSERT_TRUE(pwm);
  EXPECT_GT(pwm->yaw_us, 1500);
}

TEST_F(GroundStationTest, GivenNoFreshPoseWhenTakeOffIsAskedThenItIsRefusedAndNothingChanges) {
  ASSERT_EQ(station.command(kStartUs, OperatorCommand::kArm), "");
  const std::string why = station.command(kStartUs + 1'000'000, OperatorCommand::kTakeOff);
  EXPECT_FALSE(why.empty());
  EXPECT_EQ(station.state_json(kStartUs + 1'000'000)["state"], "armed");
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
