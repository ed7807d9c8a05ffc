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

TEST(CommandGapMonitor, ThisThreadsSchedstatIsReadableOnLinux) {
  const ThreadCpuTimes t = read_thread_cpu_times();
  if (!t.valid) GTEST_SKIP() << "no /proc/thread-self/schedstat (kernel without schedstats)";
  EXPECT_GE(t.on_cpu_ns, 0);
  EXPECT_GE(t.runqueue_ns, 0);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
