// Real-time threads of quad-control: see thread_setup.hpp.
#include "app/thread_setup.hpp"

#include "app/log_line.hpp"

namespace rgbdquad::quadcontrol {

void raise_this_thread(const slam::ThreadPriorityOptions& options, const std::string& name) {
  log_line(slam::raise_current_thread(options).describe(name));
}

ScopedThreadRaise::ScopedThreadRaise(const slam::ThreadPriorityOptions& options,
                                     const std::string& name)
    : saved_(slam::current_thread_schedule()) {
  raise_this_thread(options, name);
}

ScopedThreadRaise::~ScopedThreadRaise() { slam::restore_current_thread(saved_); }

}  // namespace rgbdquad::quadcontrol
