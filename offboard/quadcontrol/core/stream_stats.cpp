// The dashboard's stream figures: see stream_stats.hpp.
#include "core/stream_stats.hpp"

namespace rgbdquad::quadcontrol {

void StreamStats::on_frame(std::int64_t received_us, double link_latency_ms) {
  if (last_frame_us_ > 0 && received_us > last_frame_us_) {
    const double inst = 1e6 / static_cast<double>(received_us - last_frame_us_);
    fps_ = frames_ <= 1 ? inst : (1.0 - kFpsEmaWeight) * fps_ + kFpsEmaWeight * inst;
  }
  last_frame_us_ = received_us;
  ++frames_;
  latency_ms_ = link_latency_ms;
}

}  // namespace rgbdquad::quadcontrol
