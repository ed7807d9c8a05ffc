// Pose-driven command schedule: GIVEN/WHEN/THEN with time passed in, driven by an
// event simulation of the firmware link's timer (no clock, no threads).
#include "core/command_scheduler.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "tests/options_problem.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr std::int64_t kMs = 1000;

struct SendLog {
  std::vector<std::int64_t> sent_us;
  int pose_driven = 0, keep_alives = 0;
};

/// Feeds poses at their times and "sends" whenever the scheduler says a command is due, the way
/// FirmwareLink's timer does, until end_us. A pose and a due keep-alive at the same instant: the
/// pose is seen first (it rides on that command).
SendLog simulate(CommandScheduler& s, const std::vector<std::int64_t>& poses_us,
                 std::int64_t end_us, std::int64_t start_us = 0) {
  SendLog run;
  std::size_t i = 0;
  std::int64_t now = start_us;
  for (;;) {
    const std::int64_t next_send = s.next_send_us().value_or(now);
    const std::int64_t next_pose =
        i < poses_us.size() ? poses_us[i] : std::numeric_limits<std::int64_t>::max();
    if (std::min(next_send, next_pose) > end_us) break;
    if (next_pose <= next_send) {
      now = next_pose;
      s.on_pose(now);
      ++i;
      continue;
    }
    now = next_send;
    (s.on_sent(now) ? run.pose_driven : run.keep_alives)++;
    run.sent_us.push_back(now);
  }
  return run;
}

TEST(CommandScheduler, GivenNothingSentYetThenTheFirstCommandIsDueAtOnce) {
  CommandScheduler s;
  EXPECT_FALSE(s.next_send_us().has_value());
  EXPECT_TRUE(s.due(0));
}

TEST(CommandScheduler, GivenNoPosesThenKeepAlivesGoOutAtTheKeepAlivePeriod) {
  // GIVEN the default schedule (11 ms minimum, 50 ms keep-alive) and SLAM producing nothing
  CommandScheduler s;
  // WHEN 300 ms pass
  const SendLog run = simulate(s, {}, 300 * kMs);
  // THEN a command every 50 ms (the first at once): the 250 ms firmware failsafe never fires
  const std::vector<std::int64_t> expected{0,         50 * kMs,  100 * kMs, 150 * kMs,
                                           200 * kMs, 250 * kMs, 300 * kMs};
  EXPECT_EQ(run.sent_us, expected);
  EXPECT_EQ(run.pose_driven, 0);
}

TEST(CommandScheduler, GivenAPoseBurstThenCommandsAreRateLimitedAndTheBurstCoalesced) {
  // GIVEN a command sent at t = 0 and a burst of 20 poses 1 ms apart from t = 1 ms (a SLAM backlog)
  CommandScheduler s;
  std::vector<std::int64_t> poses;
  for (int k = 1; k <= 20; ++k) poses.push_back(k * kMs);
  // WHEN the link runs to 60 ms
  const SendLog run = simulate(s, poses, 60 * kMs);
  // THEN no two commands are closer than the minimum interval, and the burst costs two commands
  // (11 ms and 22 ms), not twenty; then the keep-alive period resumes from the last one
  const std::vector<std::int64_t> expected{0, 11 * kMs, 22 * kMs};
  EXPECT_EQ(run.sent_us, expected);
  EXPECT_EQ(run.pose_driven, 2);
  for (std::size_t k = 1; k < run.sent_us.size(); ++k) {
    EXPECT_GE(run.sent_us[k] - run.sent_us[k - 1], s.options().min_interval_us);
  }
}

TEST(CommandScheduler, PoseTimingTable) {
  // GIVEN a command sent at t = 0, WHEN one pose arrives at `pose_ms`, THEN its command goes at
  // `sent_ms`.
  struct Row {
    const char* name;
    std::int64_t min_interval_ms, keep_alive_ms, pose_ms, sent_ms;
  };
  const Row table[] = {
      {"right after a send: waits for the minimum interval", 17, 50, 1, 17},
      {"just before the minimum interval: waits the rest", 17, 50, 16, 17},
      {"at the minimum interval: at once", 17, 50, 17, 17},
      {"after the minimum interval: at once", 17, 50, 33, 33},
      {"just before the keep-alive: at once, no keep-alive first", 17, 50, 49, 49},
      {"a longer minimum interval (another firmware)", 30, 60, 5, 30},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    CommandScheduler s({row.min_interval_ms * kMs, row.keep_alive_ms * kMs});
    ASSERT_EQ(testing::problem(s.options()), "");
    s.on_sent(0);
    s.on_pose(row.pose_ms * kMs);
    ASSERT_TRUE(s.next_send_us().has_value());
    EXPECT_EQ(*s.next_send_us(), row.sent_ms * kMs);
    EXPECT_FALSE(s.due(row.sent_ms * kMs - 1));
    EXPECT_TRUE(s.due(row.sent_ms * kMs));
    EXPECT_TRUE(s.on_sent(row.sent_ms * kMs));  // pose-driven
    EXPECT_FALSE(s.pose_pending());
    EXPECT_EQ(*s.next_send_us(), (row.sent_ms + row.keep_alive_ms) * kMs);  // keep-alive from there
  }
}

TEST(CommandScheduler, GivenPosesAt30FpsThenEachIsSentOnArrivalAndNoKeepAliveIsNeeded) {
  // GIVEN poses every 33.333 ms (a 30 fps camera, SLAM keeping up), starting 20 ms after a first
  // command
  CommandScheduler s;
  std::vector<std::int64_t> poses;
  for (int k = 0; k < 30; ++k) poses.push_back(20 * kMs + k * 33333);
  // WHEN the link runs for a second
  const SendLog run = simulate(s, poses, poses.back());
  // THEN every pose is sent the instant it arrives (no added latency) and no keep-alive is sent
  ASSERT_EQ(run.sent_us.size(), poses.size() + 1);
  for (std::size_t k = 0; k < poses.size(); ++k) EXPECT_EQ(run.sent_us[k + 1], poses[k]);
  EXPECT_EQ(run.keep_alives, 1);  // only the very first command, before any pose
}

TEST(CommandScheduler, GivenPosesThatStopThenKeepAlivesTakeOverAtThePeriod) {
  // GIVEN poses at 30 fps for 100 ms, then SLAM stops (tracking lost, slam-server gone)
  CommandScheduler s;
  const std::vector<std::int64_t> poses{20 * kMs, 53 * kMs, 86 * kMs};
  // WHEN the link runs to 300 ms
  const SendLog run = simulate(s, poses, 300 * kMs);
  // THEN after the last pose's command, keep-alives every 50 ms: the largest gap stays far below
  // 250 ms
  const std::vector<std::int64_t> expected{0,         20 * kMs,  53 * kMs,  86 * kMs,
                                           136 * kMs, 186 * kMs, 236 * kMs, 286 * kMs};
  EXPECT_EQ(run.sent_us, expected);
  EXPECT_EQ(run.pose_driven, 3);
}

TEST(CommandScheduler, GivenAWithheldCommandThenTheSlotCountsAndThePoseIsConsumed) {
  // GIVEN a pending pose; WHEN the link withholds the command (blind landing: nothing is sent) and
  // reports the slot used, THEN the pose is consumed and the next slot is a keep-alive period later
  CommandScheduler s;
  s.on_sent(0);
  s.on_pose(20 * kMs);
  EXPECT_TRUE(s.on_sent(20 * kMs));
  EXPECT_FALSE(s.due(69 * kMs));
  EXPECT_TRUE(s.due(70 * kMs));
}

TEST(CommandScheduleOptions, ValidateTable) {
  struct Row {
    const char* name;
    std::int64_t min_interval_us, keep_alive_us;
    bool valid;
  };
  const Row table[] = {
      {"defaults", 11000, 50000, true},
      {"keep-alive equal to the minimum", 20000, 20000, true},
      {"minimum below 1 ms", 500, 50000, false},
      {"keep-alive shorter than the minimum", 20000, 10000, false},
      {"keep-alive above half the failsafe", 17000, 126000, false},
      {"keep-alive at half the failsafe", 17000, 125000, true},
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    const CommandScheduleOptions options{row.min_interval_us, row.keep_alive_us};
    EXPECT_EQ(testing::problem(options).empty(), row.valid);
  }
  EXPECT_EQ(testing::problem(CommandScheduleOptions{}), "");
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
