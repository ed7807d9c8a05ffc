// Command gap explanations: see command_gap.hpp.
#include "app/command_gap.hpp"

#include <cstdio>
#include <fstream>

namespace rgbdquad::quadcontrol {

namespace {
constexpr double kMsPerUs = 1e-3;
constexpr double kMsPerNs = 1e-6;
}  // namespace

ThreadCpuTimes read_thread_cpu_times() {
  // schedstat: "<on-cpu ns> <runqueue wait ns> <timeslices>"
  // (Documentation/scheduler/sched-stats.rst).
  std::ifstream in("/proc/thread-self/schedstat");
  ThreadCpuTimes t;
  if (in >> t.on_cpu_ns >> t.runqueue_ns) t.valid = true;
  return t;
}

CommandGapMonitor::CommandGapMonitor(std::int64_t threshold_us) : threshold_us_(threshold_us) {}

std::optional<std::string> CommandGapMonitor::on_sent(std::int64_t now_us,
                                                      const ThreadCpuTimes& cpu,
                                                      const CommandGapCauses& causes) {
  const std::optional<std::int64_t> last = last_sent_us_;
  const ThreadCpuTimes last_cpu = last_cpu_;
  last_sent_us_ = now_us;
  last_cpu_ = cpu;
  if (!last) return std::nullopt;
  const std::int64_t gap_us = now_us - *last;
  if (gap_us > max_gap_us_) max_gap_us_ = gap_us;
  if (gap_us <= threshold_us_) return std::nullopt;
  ++gaps_;
  char line[512];
  int n = std::snprintf(
      line, sizeof line,
      "%.1f ms without a command: send late %.1f ms, provider (hub lock + controller) %.1f ms, "
      "longest reply callback %.1f ms, waited for a free client %.1f ms, %llu timeouts, "
      "%llu errors, %llu withheld by the controller",
      gap_us * kMsPerUs, causes.late_us * kMsPerUs, causes.provider_us * kMsPerUs,
      causes.max_reply_callback_us * kMsPerUs, causes.waited_for_client_us * kMsPerUs,
      static_cast<unsigned long long>(causes.timeouts),
      static_cast<unsigned long long>(causes.errors),
      static_cast<unsigned long long>(causes.withheld));
  std::string out(line, n > 0 ? static_cast<std::size_t>(n) : 0);
  if (cpu.valid && last_cpu.valid) {
    const double on_cpu_ms = (cpu.on_cpu_ns - last_cpu.on_cpu_ns) * kMsPerNs;
    const double runqueue_ms = (cpu.runqueue_ns - last_cpu.runqueue_ns) * kMsPerNs;
    n = std::snprintf(
        line, sizeof line,
        "; this thread meanwhile: %.1f ms on a CPU, %.1f ms runnable waiting for a CPU, %.1f ms "
        "blocked or asleep",
        on_cpu_ms, runqueue_ms, gap_us * kMsPerUs - on_cpu_ms - runqueue_ms);
    if (n > 0) out.append(line, static_cast<std::size_t>(n));
  }
  return out;
}

}  // namespace rgbdquad::quadcontrol
