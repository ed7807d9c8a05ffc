// Command gap explanations: see command_gap.hpp.
#include "app/command_gap.hpp"

#include <algorithm>
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

std::optional<std::string> CommandGapMonitor::on_withheld(std::int64_t now_us) {
  note_ask(now_us);
  if (first_withheld_us_) return std::nullopt;
  first_withheld_us_ = now_us;
  std::string out =
      "the controller withholds its commands (blind landing: the firmware's failsafe lands the "
      "craft, by design)";
  if (last_sent_us_) {
    char line[64];
    const int n = std::snprintf(line, sizeof line, "; %.1f ms after the last command",
                                static_cast<double>(now_us - *last_sent_us_) * kMsPerUs);
    if (n > 0) out.append(line, static_cast<std::size_t>(n));
  }
  return out;
}

void CommandGapMonitor::note_ask(std::int64_t now_us) {
  if (last_asked_us_) {
    const std::int64_t pause_us = now_us - *last_asked_us_;
    gap_max_pause_us_ = std::max(gap_max_pause_us_, pause_us);
    max_pause_us_ = std::max(max_pause_us_, pause_us);
  }
  last_asked_us_ = now_us;
}

std::optional<std::string> CommandGapMonitor::on_sent(std::int64_t now_us,
                                                      const ThreadCpuTimes& cpu,
                                                      const CommandGapCauses& causes) {
  note_ask(now_us);
  const std::optional<std::int64_t> last = last_sent_us_;
  const ThreadCpuTimes last_cpu = last_cpu_;
  const std::optional<std::int64_t> withheld_from_us = first_withheld_us_;
  const std::int64_t link_pause_us = gap_max_pause_us_;
  last_sent_us_ = now_us;
  last_cpu_ = cpu;
  first_withheld_us_.reset();
  gap_max_pause_us_ = 0;
  if (!last) return std::nullopt;
  const std::int64_t gap_us = now_us - *last;
  if (gap_us > max_gap_us_) max_gap_us_ = gap_us;
  if (gap_us <= threshold_us_) return std::nullopt;
  ++gaps_;
  char line[512];
  int n = std::snprintf(line, sizeof line, "%.1f ms without a command", gap_us * kMsPerUs);
  std::string out(line, n > 0 ? static_cast<std::size_t>(n) : 0);
  if (withheld_from_us) {
    // The controller's hand-over, not a pause of the link: say so first, so that the line is not
    // read as a link fault, and give the link's own longest pause as its health.
    n = std::snprintf(line, sizeof line,
                      ", withheld by the controller from %.1f ms on (blind landing: the "
                      "firmware's failsafe lands the craft, by design); the link's longest pause "
                      "between two asks %.1f ms",
                      (*withheld_from_us - *last) * kMsPerUs, link_pause_us * kMsPerUs);
    if (n > 0) out.append(line, static_cast<std::size_t>(n));
  }
  n = std::snprintf(
      line, sizeof line,
      ": send late %.1f ms, provider (hub lock + controller) %.1f ms, "
      "longest reply callback %.1f ms, waited for a free client %.1f ms, %llu timeouts, "
      "%llu errors, %llu withheld by the controller",
      causes.late_us * kMsPerUs, causes.provider_us * kMsPerUs,
      causes.max_reply_callback_us * kMsPerUs, causes.waited_for_client_us * kMsPerUs,
      static_cast<unsigned long long>(causes.timeouts),
      static_cast<unsigned long long>(causes.errors),
      static_cast<unsigned long long>(causes.withheld));
  if (n > 0) out.append(line, static_cast<std::size_t>(n));
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
