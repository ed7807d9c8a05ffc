// CommandGapMonitor: which gaps between commands are reported, and what the report says (time and
// CPU samples passed in; no clock).
#include "app/command_gap.hpp"

#include <gtest/gtest.h>

namespace rgbdquad::quadcontrol {
namespace {

ThreadCpuTimes cpu(std::int64_t on_cpu_ms, std::int64_t runqueue_ms) {
  return ThreadCpuTimes{true, on_cpu_ms * 1000000, runqueue_ms * 1000000};
}

TEST(CommandGapMonitor, GivenGapsUpToTheThresholdThenNothingIsReported) {
  CommandGapMonitor m(100000);
  EXPECT_FALSE(m.on_sent(0, cpu(0, 0), {}));
  EXPECT_FALSE(m.on_sent(50000, cpu(1, 0), {}));
  EXPECT_FALSE(m.on_sent(150000, cpu(2, 0), {}));  // exactly the threshold
  EXPECT_EQ(m.gaps(), 0u);
  EXPECT_EQ(m.max_gap_us(), 100000);
}

TEST(CommandGapMonitor, GivenALongGapThenItIsReportedWithItsCauses) {
  CommandGapMonitor m(100000);
  m.on_sent(1000000, cpu(10, 5), {});
  CommandGapCauses c;
  c.late_us = 240000;
  c.provider_us = 3000;
  c.timeouts = 2;
  const auto line = m.on_sent(1300000, cpu(12, 245), c);
  ASSERT_TRUE(line);
  EXPECT_NE(line->find("300.0 ms without a command"), std::string::npos) << *line;
  EXPECT_NE(line->find("send late 240.0 ms"), std::string::npos) << *line;
  EXPECT_NE(line->find("2 timeouts"), std::string::npos) << *line;
  // 2 ms on a CPU, 240 ms waiting for one, the remaining 58 ms blocked or asleep.
  EXPECT_NE(line->find("2.0 ms on a CPU, 240.0 ms runnable waiting for a CPU, 58.0 ms blocked"),
            std::string::npos)
      << *line;
  EXPECT_EQ(m.gaps(), 1u);
  EXPECT_EQ(m.max_gap_us(), 300000);
}

TEST(CommandGapMonitor, GivenNoSchedstatThenTheCpuPartIsLeftOut) {
  CommandGapMonitor m(100000);
  m.on_sent(0, ThreadCpuTimes{}, {});
  const auto line = m.on_sent(200000, ThreadCpuTimes{}, {});
  ASSERT_TRUE(line);
  EXPECT_EQ(line->find("on a CPU"), std::string::npos) << *line;
}

TEST(CommandGapMonitor, GivenABlindLandingThenTheGapIsReportedAsTheHandOverNotAsALinkPause) {
  // GIVEN commands every 50 ms, then the controller withholding every ask (keep-alives every
  // 50 ms) for the 8 s blind landing, then a command again (arm=0 after the landing)
  CommandGapMonitor m(100000);
  m.on_sent(1000000, cpu(10, 0), {});
  m.on_sent(1050000, cpu(11, 0), {});
  // WHEN the first ask is withheld THEN the hand-over's start is reported once
  const auto start = m.on_withheld(1100000);
  ASSERT_TRUE(start);
  EXPECT_NE(start->find("withholds its commands (blind landing"), std::string::npos) << *start;
  EXPECT_NE(start->find("50.0 ms after the last command"), std::string::npos) << *start;
  std::int64_t t = 1100000;
  for (int i = 0; i < 160; ++i) {
    t += 50000;
    EXPECT_FALSE(m.on_withheld(t)) << "at " << t;
  }
  CommandGapCauses c;
  c.withheld = 161;
  const auto line = m.on_sent(t + 50000, cpu(23, 0), c);
  // THEN the gap names the hand-over, when it began, and the link's own longest pause (50 ms)
  ASSERT_TRUE(line);
  EXPECT_NE(line->find("8100.0 ms without a command, withheld by the controller from 50.0 ms on "
                       "(blind landing"),
            std::string::npos)
      << *line;
  EXPECT_NE(line->find("the link's longest pause between two asks 50.0 ms"), std::string::npos)
      << *line;
  EXPECT_NE(line->find("161 withheld by the controller"), std::string::npos) << *line;
  EXPECT_EQ(m.max_gap_us(), 8100000);
  EXPECT_EQ(m.max_pause_us(), 50000);
}

TEST(CommandGapMonitor, GivenTheLinkPausedDuringAHandOverThenThePauseIsReported) {
  // GIVEN a hand-over during which the link asked nothing for 300 ms (a starved thread)
  CommandGapMonitor m(100000);
  m.on_sent(0, cpu(0, 0), {});
  m.on_withheld(50000);
  m.on_withheld(350000);
  const auto line = m.on_sent(400000, cpu(1, 0), {});
  // THEN that pause is the link's, reported as such, and counted in max_pause_us()
  ASSERT_TRUE(line);
  EXPECT_NE(line->find("the link's longest pause between two asks 300.0 ms"), std::string::npos)
      << *line;
  EXPECT_EQ(m.max_pause_us(), 300000);
  // AND WHEN the next gap is the link's alone THEN it is not told as a hand-over, and a new
  // hand-over is reported when it starts
  const auto plain = m.on_sent(600000, cpu(2, 0), {});
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->find("withheld by the controller from"), std::string::npos) << *plain;
  EXPECT_NE(plain->find("200.0 ms without a command: send late"), std::string::npos) << *plain;
  EXPECT_TRUE(m.on_withheld(650000));
}

TEST(CommandGapMonitor, GivenNoCommandYetThenTheHandOverStartNamesNoDelay) {
  CommandGapMonitor m(100000);
  const auto start = m.on_withheld(0);
  ASSERT_TRUE(start);
  EXPECT_EQ(start->find("after the last command"), std::string::npos) << *start;
  EXPECT_FALSE(m.on_withheld(50000));
}

TEST(CommandGapMonitor, ThisThreadsSchedstatIsReadableOnLinux) {
  const ThreadCpuTimes t = read_thread_cpu_times();
  if (!t.valid) GTEST_SKIP() << "no /proc/thread-self/schedstat (kernel without schedstats)";
  EXPECT_GE(t.on_cpu_ns, 0);
  EXPECT_GE(t.runqueue_ns, 0);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
