// TUM replay frame source: see frame_source.hpp.
#include "app/frame_source.hpp"

#include <chrono>
#include <thread>

namespace rgbdquad::quadcontrol {

std::int64_t monotonic_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool parse_replay_loop(const std::string& name, ReplayLoop* out) {
  if (name == "once")
    *out = ReplayLoop::kOnce;
  else if (name == "wrap")
    *out = ReplayLoop::kWrap;
  else if (name == "bounce")
    *out = ReplayLoop::kBounce;
  else
    return false;
  return true;
}

std::unique_ptr<TumReplaySource> TumReplaySource::open(const TumReplayOptions& options,
                                                       std::string* error) {
  if (!(options.speed > 0.0 && options.speed <= 100.0)) {
    *error = "stream.speed must be in (0, 100]";
    return nullptr;
  }
  slam::Intrinsics intrinsics;
  if (!slam::Intrinsics::from_name(options.camera, &intrinsics, error)) return nullptr;
  auto dataset = slam::TumDataset::open(options.folder, slam::TumDatasetOptions{}, error);
  if (!dataset) return nullptr;
  if (dataset->size() < 2) {
    *error = "TUM folder " + options.folder + " has fewer than 2 associated frames";
    return nullptr;
  }
  return std::unique_ptr<TumReplaySource>(
      new TumReplaySource(options, std::move(*dataset), intrinsics));
}

TumReplaySource::TumReplaySource(TumReplayOptions options, slam::TumDataset dataset,
                                 slam::Intrinsics intrinsics)
    : options_(std::move(options)), dataset_(std::move(dataset)), intrinsics_(intrinsics) {}

std::string TumReplaySource::describe() const {
  return "TUM replay of " + options_.folder + " (" + std::to_string(dataset_.size()) + " frames)";
}

std::optional<CameraFrame> TumReplaySource::next(const std::atomic<bool>& stop,
                                                 std::string* error) {
  const auto n = static_cast<std::int64_t>(dataset_.size());
  if (position_ >= n || position_ < 0) {
    if (options_.loop == ReplayLoop::kOnce) {
      *error = "replay finished";
      return std::nullopt;
    }
    if (options_.loop == ReplayLoop::kWrap) {
      position_ = 0;
    } else {
      direction_ = -direction_;
      position_ = direction_ > 0 ? 1 : n - 2;
    }
  }
  const auto period_us =
      static_cast<std::int64_t>(dataset_.frame_period_s() * 1e6 / options_.speed);
  const std::int64_t now = monotonic_now_us();
  if (!next_due_us_) next_due_us_ = now;
  while (!stop.load() && monotonic_now_us() < *next_due_us_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  if (stop.load()) return std::nullopt;
  *next_due_us_ += period_us;
  if (*next_due_us_ < monotonic_now_us() - 10 * period_us)
    *next_due_us_ = monotonic_now_us();  // fell behind

  const std::int64_t load_start = monotonic_now_us();
  auto frame = dataset_.load(static_cast<std::size_t>(position_), error);
  if (!frame) return std::nullopt;
  CameraFrame out;
  out.sequence = delivered_++;
  // Sensor clock: keeps increasing across loops (bounce/wrap) so downstream time never goes back.
  out.capture_us = out.sequence * period_us;
  out.received_us = monotonic_now_us();
  out.link_latency_ms = static_cast<double>(out.received_us - load_start) / 1000.0;
  out.rgb = frame->rgb;
  out.depth = frame->depth;
  out.intrinsics = intrinsics_;
  // accelerometer.txt's sample, moved onto the replay's clock with its offset from the colour
  // stamp kept (the gate's staleness check compares the two).
  const slam::TumEntry& entry = dataset_.entry(static_cast<std::size_t>(position_));
  if (entry.accel) {
    out.accel = *entry.accel;
    out.accel->stamp_s =
        static_cast<double>(out.capture_us) * 1e-6 + (entry.accel->stamp_s - entry.rgb_stamp_s);
  }
  position_ += direction_;
  return out;
}

}  // namespace rgbdquad::quadcontrol
