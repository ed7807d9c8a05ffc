// In-process SLAM link: see slam_link.hpp.
#include "app/slam_link.hpp"

#include "app/thread_setup.hpp"

namespace rgbdquad::quadcontrol {

std::unique_ptr<InProcessSlam> InProcessSlam::create(const slam::Intrinsics& intrinsics,
                                                     Callback callback,
                                                     const slam::ThreadPriorityOptions& priority,
                                                     std::string* error) {
  // The system that flies (as slam-server's default): ORB, tracking against a local map on this
  // link's thread, local mapping on the pipeline's own thread.
  slam::PipelineOptions options;
  options.frontend.features.kind = slam::DetectorKind::kOrb;
  options.backend.kind = slam::BackendKind::kLocalMap;
  options.mode = slam::PipelineMode::kLive;
  auto pipeline = slam::Pipeline::create(options, intrinsics, error);
  if (!pipeline) return nullptr;
  return std::unique_ptr<InProcessSlam>(
      new InProcessSlam(std::move(pipeline), std::move(callback), priority));
}

InProcessSlam::InProcessSlam(std::unique_ptr<slam::Pipeline> pipeline, Callback callback,
                             slam::ThreadPriorityOptions priority)
    : pipeline_(std::move(pipeline)), callback_(std::move(callback)) {
  // Tracking runs on this thread (the real-time path); the pipeline's mapper lowers itself.
  thread_ = std::thread([this, priority] {
    slam::name_current_thread("qc-slam-track");
    raise_this_thread(priority, "SLAM (in-process tracking)");
    run();
  });
}

InProcessSlam::~InProcessSlam() {
  mailbox_.close();
  if (thread_.joinable()) thread_.join();
  pipeline_->finish();
}

bool InProcessSlam::submit(const CameraFrame& frame) { return mailbox_.offer(frame); }

SlamStats InProcessSlam::stats() const { return mailbox_.stats(); }

void InProcessSlam::run() {
  while (auto taken = mailbox_.take()) {
    const CameraFrame& frame = *taken;
    slam::RgbdFrame input;
    input.index = frame.sequence;
    input.stamp_s = slam::seconds_from_us(frame.capture_us);
    input.rgb = frame.rgb;
    input.depth = frame.depth;
    input.q_nav_cam = frame.q_ned_cam;
    accel_gate_.attach(input.stamp_s, frame.accel, &input);  // stamp_s is the colour capture
    std::string error;
    std::optional<slam::FrameRecord> rec;
    try {
      pipeline_->submit(std::move(input));
      rec = pipeline_->record(frame.sequence);
      if (rec && !rec->ok) error = rec->error;
    } catch (const std::exception& e) {  // nothing escapes the thread
      error = std::string("SLAM threw: ") + e.what();
    }
    const bool ok = rec && rec->ok;
    SlamResult result;
    result.frame_sequence = frame.sequence;
    result.capture_us = frame.capture_us;
    result.latency_ms = static_cast<double>(monotonic_now_us() - frame.received_us) / 1000.0;
    if (ok) {
      result.state = slam::to_string(rec->state);
      result.tracking = rec->state == slam::TrackingState::kTracking;
      result.T_world_cam = rec->T_world_cam;
      result.inliers = rec->inliers;
      result.map_correction_count = static_cast<std::uint32_t>(rec->map_corrections);
    } else {
      result.state = "lost";
    }
    mailbox_.finish(ok, result.latency_ms, error);
    if (callback_) callback_(result, frame);
  }
}

}  // namespace rgbdquad::quadcontrol
