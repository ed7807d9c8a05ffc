// Live frame source over offboard/receiver: see receiver_source.hpp.
#include "app/receiver_source.hpp"

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <cstring>
#include <opencv2/imgproc.hpp>

namespace rgbdquad::quadcontrol {

namespace {
constexpr int kWaitSliceMs = 100;  // how often next() checks the stop flag while no frame comes

// The receiver's connection events and (rate-limited) errors on quad-control's stderr: who
// connected, why a connection was dropped or refused.
std::shared_ptr<spdlog::logger> receiver_logger() {
  auto log = std::make_shared<spdlog::logger>("receiver",
                                              std::make_shared<spdlog::sinks::stderr_sink_mt>());
  log->set_pattern("quad-control: receiver: %v");
  return log;
}
}  // namespace

ReceiverSource::ReceiverSource(const receiver::ReceiverOptions& options)
    : options_(options),
      receiver_(std::make_unique<receiver::StreamReceiver>(
          options, [] { return monotonic_now_us(); }, receiver_logger())) {}

std::string ReceiverSource::describe() const {
  return "rgbd-streamer via receiver on " + options_.bind_address + ":" +
         std::to_string(receiver_->rgb_port()) + " (RGB) / " +
         std::to_string(receiver_->depth_port()) + " (depth)";
}

std::optional<CameraFrame> ReceiverSource::next(const std::atomic<bool>& stop, std::string* error) {
  while (!stop.load()) {
    auto pair = receiver_->wait_for_pair(last_pair_id_, kWaitSliceMs);
    if (!pair) continue;
    last_pair_id_ = pair->pair_id;
    const auto& rgb = *pair->rgb;
    const auto& depth = *pair->depth;
    if (rgb.info.width != depth.info.width || rgb.info.height != depth.info.height) {
      *error = "RGB and depth sizes differ (depth must be registered to RGB)";
      return std::nullopt;
    }
    CameraFrame f;
    f.sequence = delivered_++;
    f.capture_us = rgb.info.capture_timestamp_us;
    f.received_us = std::max(rgb.info.receive_timestamp_us, depth.info.receive_timestamp_us);
    f.link_latency_ms =
        static_cast<double>(std::max(rgb.info.decode_us, depth.info.decode_us)) / 1000.0;
    cv::Mat rgb_view(rgb.info.height, rgb.info.width, CV_8UC3,
                     const_cast<std::uint8_t*>(rgb.rgb.data()));
    cv::cvtColor(rgb_view, f.rgb, cv::COLOR_RGB2BGR);
    f.depth = cv::Mat(depth.info.height, depth.info.width, CV_16UC1);
    std::memcpy(f.depth.data, depth.depth.data(), depth.depth.size() * sizeof(std::uint16_t));
    const auto& k = pair->intrinsics;
    f.intrinsics.fx_px = k.fx_px;
    f.intrinsics.fy_px = k.fy_px;
    f.intrinsics.cx_px = k.cx_px;
    f.intrinsics.cy_px = k.cy_px;
    for (std::size_t i = 0; i < 5; ++i) f.intrinsics.distortion[i] = k.distortion[i];
    f.intrinsics.depth_units_per_m = depth.units_per_m;
    if (rgb.accel.valid) {
      const auto& a = rgb.accel;
      f.accel = slam::AccelSample{static_cast<double>(a.capture_timestamp_us) * 1e-6,
                                  Eigen::Vector3d(a.f_mps2[0], a.f_mps2[1], a.f_mps2[2])};
    }
    if (rgb.encoded && rgb.info.encoding == protocol::Encoding::kRgbJpeg)
      f.rgb_encoded = {"jpeg", rgb.encoded};
    if (depth.encoded && depth.info.encoding == protocol::Encoding::kDepthRvl)
      f.depth_encoded = {"rvl", depth.encoded};
    if (depth.encoded && depth.info.encoding == protocol::Encoding::kDepthZstdDelta)
      f.depth_encoded = {"zstd-delta", depth.encoded};
    return f;
  }
  return std::nullopt;
}

}  // namespace rgbdquad::quadcontrol
