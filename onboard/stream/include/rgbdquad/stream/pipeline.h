// The streamer's per-frame path: source -> validation (blank/malformed dropped and counted, never
// sent) -> depth-to-RGB registration where the source did not register -> the RGB or depth
// sender's newest-frame mailbox. Also formats the periodic counters line.
//
// Thread safety: step()/run() on one thread; counters() from any thread.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/depth_registration.h"
#include "rgbdquad/capture/frame_source.h"
#include "rgbdquad/capture/frame_validator.h"
#include "rgbdquad/stream/stream_sender.h"

namespace rgbdquad::stream {

struct PipelineCounters {
  std::uint64_t captured = 0;
  std::uint64_t unregistered_dropped = 0;  // depth not registered and no calibration to do it
  capture::ValidationCounters validation;
  SenderCounters rgb;
  SenderCounters depth;
};

// "captured 300 sent rgb 290 depth 288 dropped blank 2 malformed 0 superseded 20 ..." with rates
// over the interval since `previous` (interval_us > 0).
std::string format_stats(const PipelineCounters& now, const PipelineCounters& previous,
                         std::int64_t interval_us);

class StreamerPipeline {
 public:
  // All references must outlive the pipeline. `registration` empty: depth that is not already
  // registered is dropped (counted) rather than sent misaligned.
  StreamerPipeline(capture::FrameSource* source, const capture::FrameValidatorOptions& validation,
                   std::optional<capture::RegistrationOptions> registration, StreamSender* rgb,
                   StreamSender* depth);

  // Takes one frame from the source and routes it; false at end of stream / after stop.
  bool step();
  // step() until the source ends or `stop` is set; logs format_stats() every stats_period_us of
  // `clock` time (0 = never).
  void run(const std::atomic<bool>& stop, capture::Clock* clock, std::int64_t stats_period_us,
           spdlog::logger* log);
  PipelineCounters counters() const;

 private:
  capture::FrameSource* source_;
  capture::FrameValidator validator_;
  std::optional<capture::DepthRegistration> registration_;
  StreamSender* rgb_;
  StreamSender* depth_;
  mutable std::mutex mutex_;
  std::uint64_t captured_ = 0;
  std::uint64_t unregistered_dropped_ = 0;
  capture::ValidationCounters validation_counters_;
};

}  // namespace rgbdquad::stream
