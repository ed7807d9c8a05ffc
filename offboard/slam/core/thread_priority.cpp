// Thread scheduling of the real-time path; see thread_priority.hpp.
#include "slam/core/thread_priority.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

namespace rgbdquad::slam {
namespace {

// sched_get_priority_{min,max}(SCHED_RR) on Linux; nice range of setpriority(2).
constexpr int kMinRtPriority = 1;
constexpr int kMaxRtPriority = 99;
constexpr int kMinNice = -20;
constexpr int kMaxNice = 19;

std::string errno_text(int err) {
  if (err == EPERM)
    return std::string(std::strerror(err)) + " (needs CAP_SYS_NICE or RLIMIT_RTPRIO)";
  return std::strerror(err);
}

// setpriority(PRIO_PROCESS, tid) sets the nice value of one thread on Linux.
bool set_thread_nice(int nice, std::string* error) {
  if (::setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), nice) == 0) return true;
  *error = "setpriority(nice " + std::to_string(nice) + "): " + errno_text(errno);
  return false;
}

ThreadPriorityResult apply_nice(int nice, std::string reason) {
  ThreadPriorityResult r;
  std::string err;
  if (set_thread_nice(nice, &err)) {
    r.applied = "nice " + std::to_string(nice);
  } else {
    r.applied = "unchanged";
    reason += (reason.empty() ? "" : "; ") + err;
  }
  r.reason = std::move(reason);
  return r;
}

}  // namespace

bool ThreadPriorityOptions::is_valid(std::string* error) const {
  const char* problem = nullptr;
  if (rt_priority < kMinRtPriority || rt_priority > kMaxRtPriority)
    problem = "rt_priority must be in [1, 99]";
  else if (fallback_nice < kMinNice || fallback_nice > kMaxNice)
    problem = "fallback_nice must be in [-20, 19]";
  if (problem && error) *error = problem;
  return problem == nullptr;
}

bool parse_thread_policy(const std::string& name, ThreadPolicy* out, std::string* error) {
  if (name == "off") {
    *out = ThreadPolicy::kOff;
    return true;
  }
  if (name == "nice") {
    *out = ThreadPolicy::kNice;
    return true;
  }
  if (name == "rr") {
    *out = ThreadPolicy::kRoundRobin;
    return true;
  }
  if (name == "fifo") {
    *out = ThreadPolicy::kFifo;
    return true;
  }
  if (error) *error = "unknown thread policy '" + name + "' (expected off, nice, rr or fifo)";
  return false;
}

const char* to_string(ThreadPolicy policy) {
  switch (policy) {
    case ThreadPolicy::kOff:
      return "off";
    case ThreadPolicy::kNice:
      return "nice";
    case ThreadPolicy::kRoundRobin:
      return "rr";
    case ThreadPolicy::kFifo:
      return "fifo";
  }
  return "?";
}

std::string ThreadPriorityResult::describe(const std::string& thread_name) const {
  std::string s = thread_name + " thread: " + applied;
  if (!reason.empty()) s += " (" + reason + ")";
  return s;
}

ThreadPriorityResult raise_current_thread(const ThreadPriorityOptions& options) {
  switch (options.policy) {
    case ThreadPolicy::kOff:
      return {false, "unchanged", "thread policy off in the configuration"};
    case ThreadPolicy::kNice:
      return apply_nice(options.fallback_nice, "");
    case ThreadPolicy::kRoundRobin:
    case ThreadPolicy::kFifo:
      break;
  }
  const int policy = options.policy == ThreadPolicy::kFifo ? SCHED_FIFO : SCHED_RR;
  sched_param param{};
  param.sched_priority = options.rt_priority;
  const int err = ::pthread_setschedparam(::pthread_self(), policy, &param);
  if (err == 0) {
    return {true,
            std::string(policy == SCHED_FIFO ? "SCHED_FIFO" : "SCHED_RR") + " priority " +
                std::to_string(options.rt_priority),
            ""};
  }
  return apply_nice(options.fallback_nice, std::string("real-time policy refused: ") +
                                               errno_text(err) + "; fell back to nice");
}

ThreadPriorityResult lower_current_thread(int nice_under_normal_creator,
                                          int nice_under_realtime_creator) {
  int policy = SCHED_OTHER;
  sched_param param{};
  std::string reason;
  int nice = nice_under_normal_creator;
  if (::pthread_getschedparam(::pthread_self(), &policy, &param) == 0 &&
      (policy == SCHED_RR || policy == SCHED_FIFO)) {
    sched_param normal{};
    normal.sched_priority = 0;
    if (const int err = ::pthread_setschedparam(::pthread_self(), SCHED_OTHER, &normal); err != 0) {
      reason = std::string("stays real-time (inherited): ") + errno_text(err);
    } else {
      nice = nice_under_realtime_creator;
      reason = "below a real-time creator";
    }
  }
  ThreadPriorityResult r = apply_nice(nice, std::move(reason));
  return r;
}

ThreadSchedule current_thread_schedule() {
  ThreadSchedule s;
  sched_param param{};
  if (::pthread_getschedparam(::pthread_self(), &s.policy, &param) == 0)
    s.priority = param.sched_priority;
  s.nice = ::getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)));
  return s;
}

bool current_thread_is_realtime() {
  const int policy = current_thread_schedule().policy;
  return policy == SCHED_RR || policy == SCHED_FIFO;
}

void restore_current_thread(const ThreadSchedule& schedule) {
  sched_param param{};
  param.sched_priority = schedule.priority;
  ::pthread_setschedparam(::pthread_self(), schedule.policy, &param);  // lowering is always allowed
  std::string ignored;
  if (schedule.policy != SCHED_RR && schedule.policy != SCHED_FIFO)
    set_thread_nice(schedule.nice, &ignored);
}

void name_current_thread(const std::string& name) {
  constexpr std::size_t kMaxThreadNameChars = 15;  // TASK_COMM_LEN 16 with the terminator
  pthread_setname_np(pthread_self(), name.substr(0, kMaxThreadNameChars).c_str());
}

PriorityInheritanceMutex::PriorityInheritanceMutex(bool inherit) {
  pthread_mutexattr_t attr;
  ::pthread_mutexattr_init(&attr);
  ::pthread_mutexattr_setprotocol(&attr, inherit ? PTHREAD_PRIO_INHERIT : PTHREAD_PRIO_NONE);
  ::pthread_mutex_init(&mutex_, &attr);
  ::pthread_mutexattr_destroy(&attr);
}

PriorityInheritanceMutex::~PriorityInheritanceMutex() { ::pthread_mutex_destroy(&mutex_); }

void PriorityInheritanceMutex::lock() {
  if (const int err = ::pthread_mutex_lock(&mutex_); err != 0)
    throw std::system_error(err, std::generic_category(), "mutex lock");
}

void PriorityInheritanceMutex::unlock() { ::pthread_mutex_unlock(&mutex_); }

bool PriorityInheritanceMutex::try_lock() { return ::pthread_mutex_trylock(&mutex_) == 0; }

}  // namespace rgbdquad::slam
