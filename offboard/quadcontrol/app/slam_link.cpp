// In-process SLAM link: see slam_link.hpp.
#include "app/slam_link.hpp"

namespace rgbdquad::quadcontrol {

std::unique_ptr<InProcessSlam> InProcessSlam::create(const slam::Intrinsics& intrinsics, Callback callback,
                                                     std::string* error) {
  auto frontend = slam::FrontEnd::create(slam::FrontendOptions{}, intrinsics, error);
  if (!frontend) return nullptr;
  return std::unique_ptr<InProcessSlam>(new InProcessSlam(std::move(*frontend), std::move(callback)));
}

InProcessSlam::InProcessSlam(slam::FrontEnd frontend, Callback callback)
    : frontend_(std::move(frontend)), callback_(std::move(callback)) {
  thread_ = std::thread([this] { run(); });
}

InProcessSlam::~InProcessSlam() {
  mailbox_.close();
  if (thread_.joinable()) thread_.join();
}

bool InProcessSlam::submit(const CameraFrame& frame) { return mailbox_.offer(frame); }

SlamStats InProcessSlam::stats() const { return mailbox_.stats(); }

void InProcessSlam::run() {
  while (auto taken = mailbox_.take()) {
    const CameraFrame& frame = *taken;
    slam::RgbdFrame input;
    input.index = frame.sequence;
    input.stamp_s = static_cast<double>(frame.capture_us) / 1e6;
    input.rgb = frame.rgb;
    input.depth = frame.depth;
    std::string error;
    std::optional<slam::FrontendOutput> out;
    try {
      out = frontend_.process(input, &error);
    } catch (const std::exception& e) {  // nothing escapes the thread
      error = std::string("front-end threw: ") + e.what();
    }
    SlamResult result;
    result.frame_sequence = frame.sequence;
    result.capture_us = frame.capture_us;
    result.latency_ms = static_cast<double>(monotonic_now_us() - frame.received_us) / 1000.0;
    if (out) {
      result.state = slam::to_string(out->state);
      result.tracking = out->state == slam::TrackingState::kTracking;
      result.T_world_cam = out->T_odom_cam;
      result.inliers = out->inliers;
    } else {
      result.state = "lost";
    }
    mailbox_.finish(out.has_value(), result.latency_ms, error);
    if (callback_) callback_(result, frame);
  }
}

}  // namespace rgbdquad::quadcontrol
