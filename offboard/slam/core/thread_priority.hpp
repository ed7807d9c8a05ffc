// Scheduling of the ground station's threads: the camera-to-command path (slam-server's tracking
// loop, quad-control's frame, SLAM-link and firmware-link threads) runs under a real-time policy
// where the OS allows it, so CPU-heavy neighbours (builds, other programs) cannot delay a pose or
// a command; best-effort work beside it (local mapping, the back-end) drops back to the normal
// policy with a positive nice. Every call says what it applied and, when the OS refused, why
// (the caller logs it): no privileges (no CAP_SYS_NICE / RLIMIT_RTPRIO), a container without
// real-time bandwidth, or a policy switched off in the configuration.
#pragma once

#include <pthread.h>

#include <string>

namespace rgbdquad::slam {

enum class ThreadPolicy {
  kOff,         ///< leave the thread as it is
  kNice,        ///< normal policy, nice = fallback_nice
  kRoundRobin,  ///< SCHED_RR at rt_priority, else nice = fallback_nice
  kFifo,        ///< SCHED_FIFO at rt_priority, else nice = fallback_nice
};

struct ThreadPriorityOptions {
  ThreadPolicy policy = ThreadPolicy::kRoundRobin;
  // 10: above every normal-policy thread, below the kernel's threaded interrupt handlers (50), so
  // the network stack that carries our frames and commands is never starved by us. SCHED_RR (not
  // FIFO): threads of equal priority share a core in 100 ms slices instead of one running to
  // completion.
  int rt_priority = 10;
  // -10 when real-time is refused: a nice-0 neighbour then gets ~1/10 of the CPU weight (CFS: each
  // nice step ~1.25x), the classic "interactive" level; needs CAP_SYS_NICE too, else it is logged.
  int fallback_nice = -10;
  /// Checks the ranges; on failure returns false and, if error is not null, says which field.
  bool is_valid(std::string* error) const;
};

/// "off" | "nice" | "rr" | "fifo"; false (and *error) on anything else.
bool parse_thread_policy(const std::string& name, ThreadPolicy* out, std::string* error);
const char* to_string(ThreadPolicy policy);

struct ThreadPriorityResult {
  bool realtime = false;  ///< the thread now runs under SCHED_RR/SCHED_FIFO
  std::string applied;    ///< e.g. "SCHED_RR priority 10", "nice -10", "unchanged"
  std::string reason;     ///< why a fallback was taken (empty when the request was met)
  std::string describe(const std::string& thread_name) const;
};

/// Raises the calling thread (Linux schedules threads individually).
ThreadPriorityResult raise_current_thread(const ThreadPriorityOptions& options);

/// For a best-effort thread beside the real-time path (local mapping, the back-end): puts it on the
/// normal policy, below its creator either way. A thread inherits its creator's policy, and nice
/// has no effect under a real-time one, so without this it would compete with a raised tracker as
/// its equal. Created by a normal-policy thread: nice `nice_under_normal_creator` (yield to it by
/// weight). Created by a real-time thread: nice `nice_under_realtime_creator` - below the creator
/// by policy already, and still ahead of the machine's other normal work (a mapper at nice 10
/// beside two CPU burners got ~5 % of a core and tracking was lost in the HIL load scenario).
ThreadPriorityResult lower_current_thread(int nice_under_normal_creator,
                                          int nice_under_realtime_creator);

/// The calling thread's scheduling, to put it back after a temporary raise (threads created in
/// between inherit the raised one: how a library's internal threads join the real-time path).
struct ThreadSchedule {
  int policy = 0;
  int priority = 0;
  int nice = 0;
};
ThreadSchedule current_thread_schedule();
/// The calling thread runs under SCHED_RR or SCHED_FIFO (asked for, or inherited from its creator).
bool current_thread_is_realtime();
void restore_current_thread(const ThreadSchedule& schedule);

/// Names the calling thread so `top -H`, `ps -L` and /proc/PID/task/*/comm attribute its CPU time
/// (Linux keeps 15 characters; a longer name is cut). Instrumentation only: a failure is ignored.
void name_current_thread(const std::string& name);

/// A mutex with priority inheritance (PTHREAD_PRIO_INHERIT): a normal-policy thread holding it
/// (e.g. the dashboard building /api/state) runs at the priority of the real-time thread waiting
/// for it until it unlocks, so CPU-heavy neighbours cannot stretch the wait (priority inversion;
/// seen in the HIL: the firmware link waited 100-1000 ms for the hub's lock under load and the
/// firmware's 250 ms failsafe fired). Lockable, for std::lock_guard / std::unique_lock.
class PriorityInheritanceMutex {
 public:
  /// `inherit` false: a plain mutex (PTHREAD_PRIO_NONE), for before/after measurements.
  explicit PriorityInheritanceMutex(bool inherit = true);
  ~PriorityInheritanceMutex();
  PriorityInheritanceMutex(const PriorityInheritanceMutex&) = delete;
  PriorityInheritanceMutex& operator=(const PriorityInheritanceMutex&) = delete;
  void lock();
  void unlock();
  bool try_lock();

 private:
  pthread_mutex_t mutex_;
};

}  // namespace rgbdquad::slam
