// The scheduling of quad-control's real-time threads (frame, SLAM link, firmware link): each one
// raises itself when it starts (slam::raise_current_thread: SCHED_RR where the OS allows it, else
// nice, else unchanged) and logs what it got and why, so a run on a host without the privilege
// says so. Configured by the top-level "realtime" key (config/quad-control.json).
#pragma once

#include <string>

#include "slam/core/thread_priority.hpp"

namespace rgbdquad::quadcontrol {

/// Raises the calling thread per `options`; logs "quad-control: <name> thread: <what applied>".
void raise_this_thread(const slam::ThreadPriorityOptions& options, const std::string& name);

/// Raises the calling thread for its lifetime and puts it back afterwards: threads created in
/// between (a library's own, e.g. the stream receiver's socket threads) inherit the raised policy.
class ScopedThreadRaise {
 public:
  ScopedThreadRaise(const slam::ThreadPriorityOptions& options, const std::string& name);
  ~ScopedThreadRaise();
  ScopedThreadRaise(const ScopedThreadRaise&) = delete;
  ScopedThreadRaise& operator=(const ScopedThreadRaise&) = delete;

 private:
  slam::ThreadSchedule saved_;
};

}  // namespace rgbdquad::quadcontrol
