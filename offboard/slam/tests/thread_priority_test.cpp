// Thread scheduling of the real-time path (slam/core/thread_priority.hpp). What the OS grants
// depends on the host (root or CAP_SYS_NICE in a container, or nothing): each test checks that the
// result says what the thread really runs under, whichever way it went, and that a refusal names a
// reason. Every test runs in its own std::thread so the test runner's thread is never changed.
#include "slam/core/thread_priority.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <thread>

namespace rgbdquad::slam {
namespace {

int current_policy() {
  int policy = -1;
  sched_param p{};
  pthread_getschedparam(pthread_self(), &policy, &p);
  return policy;
}

int current_nice() { return getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid))); }

template <class F>
void on_own_thread(F f) {
  std::thread t(f);
  t.join();
}

TEST(ThreadPriority, PolicyNamesRoundTripAndBadValuesAreRefused) {
  for (const char* name : {"off", "nice", "rr", "fifo"}) {
    ThreadPolicy p{};
    ASSERT_TRUE(parse_thread_policy(name, &p, nullptr)) << name;
    EXPECT_STREQ(to_string(p), name);
  }
  ThreadPolicy p{};
  std::string error;
  EXPECT_FALSE(parse_thread_policy("realtime", &p, &error));
  EXPECT_NE(error.find("realtime"), std::string::npos);
  ThreadPriorityOptions o;
  EXPECT_TRUE(o.is_valid(&error));
  o.rt_priority = 0;
  EXPECT_FALSE(o.is_valid(&error));
  EXPECT_NE(error.find("rt_priority"), std::string::npos);
  o = ThreadPriorityOptions{};
  o.fallback_nice = -21;
  EXPECT_FALSE(o.is_valid(&error));
  EXPECT_NE(error.find("fallback_nice"), std::string::npos);
  EXPECT_FALSE(o.is_valid(nullptr));
}

TEST(ThreadPriority, OffLeavesTheThreadAsItIs) {
  on_own_thread([] {
    const int before = current_policy();
    ThreadPriorityOptions o;
    o.policy = ThreadPolicy::kOff;
    const ThreadPriorityResult r = raise_current_thread(o);
    EXPECT_FALSE(r.realtime);
    EXPECT_EQ(r.applied, "unchanged");
    EXPECT_NE(r.reason.find("off"), std::string::npos);
    EXPECT_EQ(current_policy(), before);
  });
}

TEST(ThreadPriority, RoundRobinIsAppliedOrTheFallbackSaysWhy) {
  on_own_thread([] {
    ThreadPriorityOptions o;  // rr, 10, fallback nice -10
    const ThreadPriorityResult r = raise_current_thread(o);
    if (r.realtime) {
      EXPECT_EQ(current_policy(), SCHED_RR);
      EXPECT_EQ(r.applied, "SCHED_RR priority 10");
      EXPECT_EQ(r.reason, "");
    } else {
      EXPECT_EQ(current_policy(), SCHED_OTHER);
      EXPECT_NE(r.reason.find("real-time policy refused"), std::string::npos) << r.reason;
      if (r.applied == "nice -10") {
        EXPECT_EQ(current_nice(), -10);
      }
    }
    EXPECT_NE(r.describe("test").find("test thread: "), std::string::npos);
  });
}

TEST(ThreadPriority, LoweringDropsAnInheritedRealTimePolicySoNiceApplies) {
  on_own_thread([] {
    const bool realtime = raise_current_thread(ThreadPriorityOptions{}).realtime;
    // A thread started from a real-time thread inherits its policy (pthread default).
    std::thread child([realtime] {
      if (realtime) {
        EXPECT_EQ(current_policy(), SCHED_RR);
      }
      const ThreadPriorityResult r = lower_current_thread(10, -10);
      EXPECT_EQ(current_policy(), SCHED_OTHER);
      if (realtime) {
        // Below the real-time creator by policy, ahead of normal work by nice (the privilege that
        // granted real-time grants a negative nice too).
        EXPECT_EQ(r.applied, "nice -10");
        EXPECT_EQ(current_nice(), -10);
      } else {
        EXPECT_EQ(r.applied, "nice 10");  // raising nice is always allowed
        EXPECT_EQ(current_nice(), 10);
      }
    });
    child.join();
  });
}

TEST(ThreadPriority, ASavedScheduleIsRestoredAfterATemporaryRaise) {
  on_own_thread([] {
    const ThreadSchedule before = current_thread_schedule();
    raise_current_thread(ThreadPriorityOptions{});
    restore_current_thread(before);
    const ThreadSchedule after = current_thread_schedule();
    EXPECT_EQ(after.policy, before.policy);
    EXPECT_EQ(after.priority, before.priority);
    EXPECT_EQ(after.nice, before.nice);
  });
}

}  // namespace
}  // namespace rgbdquad::slam
