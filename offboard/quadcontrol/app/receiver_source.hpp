// Live frame source: the onboard streamer's two links through the ground-station receiver library
// (offboard/receiver, rgbdquad::receiver::StreamReceiver). Listens on the RGB and depth ports; the
// newest RGB-D pair is delivered (older pairs are skipped, as the thesis dropped stale frames).
// link_latency_ms is the receiver's payload decode time: capture/send stamps are on the craft's
// clock, which is not synchronised with ours, so a one-way latency cannot be measured honestly.
#pragma once

#include <memory>
#include <string>

#include "app/frame_source.hpp"
#include "rgbdquad/receiver/stream_receiver.h"

namespace rgbdquad::quadcontrol {

class ReceiverSource : public FrameSource {
 public:
  /// Binds the ports; throws std::runtime_error (start-up boundary) when they cannot be bound.
  explicit ReceiverSource(const receiver::ReceiverOptions& options);
  std::optional<CameraFrame> next(const std::atomic<bool>& stop, std::string* error) override;
  std::string describe() const override;

 private:
  receiver::ReceiverOptions options_;
  std::unique_ptr<receiver::StreamReceiver> receiver_;
  std::uint64_t last_pair_id_ = 0;
  std::int64_t delivered_ = 0;
};

}  // namespace rgbdquad::quadcontrol
