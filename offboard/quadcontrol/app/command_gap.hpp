// Why the firmware link went quiet (a radio failsafe lands the craft after 250 ms): every gap
// between two commands longer than a threshold is explained in one log line, with what the sending
// thread was doing meanwhile:
//   * late     - how long after the send was due the link's thread ran the send (timer wake-up);
//   * provider - the command provider (the hub's lock + the controller step) of this send;
//   * reply    - the longest reply callback since the previous send (recorder + hub lock);
//   * clients  - how long a due send waited because both HTTP clients were busy (firmware/bridge
//                slow), and how many requests timed out meanwhile;
//   * CPU      - the thread's own scheduler accounting over the gap (Linux schedstat): time on a
//                CPU, time runnable but waiting for a CPU (starved by higher-priority work or RT
//                throttling), and the rest, blocked or asleep (a lock, a syscall, or simply nothing
//                due).
// A gap the controller made on purpose is told apart from one of the link: a blind landing hands
// the craft to the firmware's failsafe by withholding every command for failsafe_landing_ms (8 s),
// while the link goes on asking on schedule. Such a gap is reported as the hand-over it is, with
// the link's own longest pause between two asks, and its start is reported when it starts (the
// gap's line comes only when commanding resumes, which a killed ground station never does).
// Time and CPU samples are passed in; read_thread_cpu_times() is the only part that reads the OS.
// Not thread-safe: one owner (the firmware link's I/O thread).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace rgbdquad::quadcontrol {

/// The calling thread's cumulative scheduler times (/proc/thread-self/schedstat, nanoseconds).
struct ThreadCpuTimes {
  bool valid = false;  ///< false where schedstat is not available (then CPU is not reported)
  std::int64_t on_cpu_ns = 0;    ///< time spent running
  std::int64_t runqueue_ns = 0;  ///< time spent runnable, waiting for a CPU
};

/// Reads the calling thread's schedstat (~10 us: a /proc read); invalid on failure.
ThreadCpuTimes read_thread_cpu_times();

/// What the sending thread went through since the previous command (filled in by the link).
struct CommandGapCauses {
  std::int64_t late_us = 0;                ///< the send ran this long after it was due
  std::int64_t provider_us = 0;            ///< the provider call of this send
  std::int64_t max_reply_callback_us = 0;  ///< longest reply callback since the previous send
  std::int64_t waited_for_client_us = 0;   ///< a due send waited this long for a free client
  std::uint64_t timeouts = 0;              ///< requests timed out since the previous send
  std::uint64_t errors = 0;                ///< connect/HTTP errors since the previous send
  std::uint64_t withheld = 0;              ///< sends the provider withheld (failsafe hand-over)
};

class CommandGapMonitor {
 public:
  /// 100 ms: two keep-alive periods (50 ms) missed, 40 % of the firmware's 250 ms failsafe; a gap
  /// this long is already abnormal, and every one that grows into a failsafe is logged on the way.
  static constexpr std::int64_t kDefaultThresholdUs = 100000;

  explicit CommandGapMonitor(std::int64_t threshold_us = kDefaultThresholdUs);

  /// A command went out at now_us; `cpu` is the thread's schedstat now. Returns the log line when
  /// the gap since the previous command exceeded the threshold, else nullopt.
  std::optional<std::string> on_sent(std::int64_t now_us, const ThreadCpuTimes& cpu,
                                     const CommandGapCauses& causes);

  /// The link asked for the command of now_us and the controller withheld it (blind landing): no
  /// command went out, by design. Returns the log line of the first withheld ask since the last
  /// command (the hand-over begins), else nullopt.
  std::optional<std::string> on_withheld(std::int64_t now_us);

  std::uint64_t gaps() const { return gaps_; }             ///< gaps over the threshold so far
  std::int64_t max_gap_us() const { return max_gap_us_; }  ///< longest gap between two commands
  /// Longest time the link went without asking the controller (a command sent or withheld): the
  /// link's own health, which a blind landing's hand-over does not count against.
  std::int64_t max_pause_us() const { return max_pause_us_; }

 private:
  /// The link asked the controller at now_us (a command sent or withheld): the pause since the
  /// previous ask.
  void note_ask(std::int64_t now_us);

  std::int64_t threshold_us_;
  std::optional<std::int64_t> last_sent_us_;
  ThreadCpuTimes last_cpu_;
  std::uint64_t gaps_ = 0;
  std::int64_t max_gap_us_ = 0;
  std::int64_t max_pause_us_ = 0;
  // Since the previous command: the first and the latest withheld ask, and the longest pause
  // between two asks (the previous command counts as one).
  std::optional<std::int64_t> first_withheld_us_;
  std::optional<std::int64_t> last_asked_us_;
  std::int64_t gap_max_pause_us_ = 0;
};

}  // namespace rgbdquad::quadcontrol
