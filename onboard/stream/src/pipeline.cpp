// Capture -> validate -> register -> publish.
#include "rgbdquad/stream/pipeline.h"

#include <spdlog/spdlog.h>

namespace rgbdquad::stream {

std::string format_stats(const PipelineCounters& now, const PipelineCounters& previous,
                         std::int64_t interval_us) {
  const double seconds = static_cast<double>(interval_us) / 1e6;
  auto rate = [seconds](std::uint64_t a, std::uint64_t b) {
    return seconds > 0 ? static_cast<double>(a - b) / seconds : 0.0;
  };
  auto encode_ms = [](const SenderCounters& n, const SenderCounters& p) {
    const std::uint64_t frames = n.sent - p.sent;
    return frames == 0
               ? 0.0
               : static_cast<double>(n.encode_us_total - p.encode_us_total) / 1000.0 / frames;
  };
  const auto& v = now.validation;
  // Totals only when there is no interval (the final line), totals and rates otherwise.
  auto with_rate = [&](std::uint64_t a, std::uint64_t b) {
    return seconds > 0 ? fmt::format("{} ({:.1f}/s)", a, rate(a, b)) : fmt::format("{}", a);
  };
  const std::string bytes =
      seconds > 0
          ? fmt::format("{:.2f} MB/s", (rate(now.rgb.bytes_sent, previous.rgb.bytes_sent) +
                                        rate(now.depth.bytes_sent, previous.depth.bytes_sent)) /
                                           1e6)
          : fmt::format("{:.1f} MB sent",
                        static_cast<double>(now.rgb.bytes_sent + now.depth.bytes_sent) / 1e6);
  return fmt::format(
      "captured {} sent rgb {} depth {} dropped blank {} malformed {} out-of-order {} "
      "unregistered {} superseded rgb {} depth {} | {} | encode ms rgb {:.2f} depth {:.2f} | "
      "connected rgb {} depth {}",
      with_rate(now.captured, previous.captured), with_rate(now.rgb.sent, previous.rgb.sent),
      with_rate(now.depth.sent, previous.depth.sent), v.rgb_blank + v.depth_blank, v.malformed,
      v.out_of_order, now.unregistered_dropped, now.rgb.superseded, now.depth.superseded, bytes,
      encode_ms(now.rgb, previous.rgb), encode_ms(now.depth, previous.depth),
      now.rgb.connects - now.rgb.disconnects, now.depth.connects - now.depth.disconnects);
}

StreamerPipeline::StreamerPipeline(capture::FrameSource* source,
                                   const capture::FrameValidatorOptions& validation,
                                   std::optional<capture::RegistrationOptions> registration,
                                   StreamSender* rgb, StreamSender* depth)
    : source_(source), validator_(validation), rgb_(rgb), depth_(depth) {
  if (registration) registration_.emplace(*registration);
}

bool StreamerPipeline::step() {
  auto frame = source_->next();
  if (!frame) return false;
  const capture::Verdict verdict = validator_.check(*frame);
  bool unregistered = false;
  if (verdict == capture::Verdict::kOk) {
    if (auto* depth = std::get_if<capture::DepthFrame>(&*frame);
        depth && !depth->registered_to_rgb) {
      std::optional<capture::DepthFrame> registered;
      if (registration_) registered = registration_->register_depth(*depth);
      if (registered)
        *depth = std::move(*registered);
      else
        unregistered = true;
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++captured_;
    validation_counters_ = validator_.counters();
    if (unregistered) ++unregistered_dropped_;
  }
  if (verdict != capture::Verdict::kOk || unregistered) return true;
  if (std::holds_alternative<capture::RgbFrame>(*frame)) {
    rgb_->publish(std::move(*frame));
  } else {
    depth_->publish(std::move(*frame));
  }
  return true;
}

void StreamerPipeline::run(const std::atomic<bool>& stop, capture::Clock* clock,
                           std::int64_t stats_period_us, spdlog::logger* log) {
  PipelineCounters previous = counters();
  std::int64_t last_stats_us = clock->now_us();
  while (!stop && step()) {
    const std::int64_t now_us = clock->now_us();
    if (stats_period_us > 0 && now_us - last_stats_us >= stats_period_us && log != nullptr) {
      const PipelineCounters current = counters();
      log->info("{}", format_stats(current, previous, now_us - last_stats_us));
      previous = current;
      last_stats_us = now_us;
    }
  }
}

PipelineCounters StreamerPipeline::counters() const {
  PipelineCounters c;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    c.captured = captured_;
    c.unregistered_dropped = unregistered_dropped_;
    c.validation = validation_counters_;
  }
  c.rgb = rgb_->counters();
  c.depth = depth_->counters();
  return c;
}

}  // namespace rgbdquad::stream
