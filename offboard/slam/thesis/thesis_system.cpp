// The thesis's front-end / back-end systems; see thesis_system.hpp.
#include "slam/thesis/thesis_system.hpp"

namespace rgbdquad::slam {

std::unique_ptr<ThesisSystem> ThesisSystem::create(const PipelineOptions& o, const Intrinsics& k,
                                                   FrameRecords* records, std::string* error) {
  auto fe = FrontEnd::create(o.frontend, k, error);
  if (!fe) return nullptr;
  auto be = BackEnd::create(o.backend, error);
  if (!be) return nullptr;
  const PipelineMode mode = o.mode == PipelineMode::kLive ? PipelineMode::kSequential : o.mode;
  std::unique_ptr<ThesisSystem> s(new ThesisSystem(mode, std::move(*fe), std::move(*be), records));
  if (mode != PipelineMode::kSequential) {
    s->frontend_thread_ = std::thread([q = s.get()] { q->frontend_loop(); });
    s->backend_thread_ = std::thread([q = s.get()] { q->backend_loop(); });
  }
  return s;
}

ThesisSystem::ThesisSystem(PipelineMode mode, FrontEnd frontend, BackEnd backend,
                           FrameRecords* records)
    : mode_(mode),
      frontend_(std::move(frontend)),
      backend_(std::move(backend)),
      records_(records) {}

ThesisSystem::~ThesisSystem() { finish(); }

void ThesisSystem::submit(RgbdFrame frame) {
  if (mode_ == PipelineMode::kSequential) {
    run_frontend(frame);
  } else if (mode_ == PipelineMode::kRealtime) {
    const std::size_t dropped = input_.push_replacing(std::move(frame));
    std::lock_guard<std::mutex> lock(mutex_);
    frontend_dropped_ += dropped;
  } else {
    input_.push_waiting(std::move(frame));
  }
}

void ThesisSystem::finish() {
  if (finished_.exchange(true)) return;
  input_.close();
  if (frontend_thread_.joinable()) frontend_thread_.join();
  handover_.close();
  if (backend_thread_.joinable()) backend_thread_.join();
  joined_ = true;
}

void ThesisSystem::frontend_loop() {
  name_current_thread("slam-tracking");
  drain_stage_queue(input_, [this](const RgbdFrame& frame) { run_frontend(frame); });
}

void ThesisSystem::backend_loop() {
  name_current_thread("slam-backend");
  if (mode_ == PipelineMode::kRealtime) {
    // Real time: the front-end must keep up with the camera; the back-end is best effort (it
    // skips frames anyway), so it yields the CPU to the front-end (slam/core/thread_priority.hpp:
    // by weight under a normal front-end, by policy under a real-time one). Not fatal when refused.
    constexpr int kBackendNiceRealtime = 10;
    constexpr int kBackendNiceBelowRealtime = -10;
    lower_current_thread(kBackendNiceRealtime, kBackendNiceBelowRealtime);
  }
  drain_stage_queue(handover_, [this](const FrontendOutput& out) { run_backend(out); });
}

void ThesisSystem::run_frontend(const RgbdFrame& frame) {
  std::string error;
  std::optional<FrontendOutput> out;
  try {
    out = frontend_.process(frame, &error);
  } catch (const std::exception& e) {  // nothing escapes a thread
    error = std::string("front-end exception: ") + e.what();
  }
  FrameRecord rec;
  rec.index = frame.index;
  rec.stamp_s = frame.stamp_s;
  if (!out) {
    rec.ok = false;
    rec.error = error;
    records_->add(std::move(rec));
    return;
  }
  rec.ok = true;
  rec.state = out->state;
  rec.T_prev_cur = out->T_prev_cur;
  rec.features = out->features->points_cam_m.size();
  rec.matches = out->matches;
  rec.inliers = out->inliers;
  rec.features_ms = out->features_ms;
  rec.matching_ms = out->matching_ms;
  rec.ransac_ms = out->ransac_ms;
  rec.frontend_ms = out->total_ms;
  rec.frontend_cpu_ms = out->total_cpu_ms;
  {
    // Under mutex_ so that the back-end's correction and this record change together.
    std::lock_guard<std::mutex> lock(mutex_);
    rec.T_world_cam = correction_ * out->T_odom_cam;  // replaced when the back-end processes it
    rec.map_corrections = loop_corrections_;
    records_->add(std::move(rec));
  }
  if (mode_ == PipelineMode::kSequential) {
    run_backend(*out);
  } else if (mode_ == PipelineMode::kRealtime) {
    const std::size_t skipped = handover_.push_replacing(std::move(*out));
    std::lock_guard<std::mutex> lock(mutex_);
    backend_skipped_ += skipped;
  } else {
    handover_.push_waiting(std::move(*out));
  }
}

void ThesisSystem::run_backend(const FrontendOutput& in) {
  BackendOutput out;
  try {
    out = backend_.process(in);
  } catch (const std::exception&) {  // nothing escapes a thread; the frame keeps its VO pose
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  correction_ = out.T_world_cam * in.T_odom_cam.inverse();
  if (out.loop_closed) ++loop_corrections_;
  const std::uint64_t corrections = loop_corrections_;
  records_->update(in.index, [&](FrameRecord& r) {
    r.backend_processed = true;
    r.keyframe = out.keyframe;
    r.llc_applied = out.llc_applied;
    r.loop_closed = out.loop_closed;
    r.reference_keyframe = out.reference_keyframe;
    r.T_world_cam = out.T_world_cam;
    r.T_kf_cam = out.T_kf_cam;
    r.map_corrections = corrections;
    r.keyframe_ms = out.keyframe_ms;
    r.llc_ms = out.llc_ms;
    r.glc_ms = out.glc_ms;
    r.posegraph_ms = out.posegraph_ms;
    r.backend_ms = out.total_ms;
    r.backend_cpu_ms = out.total_cpu_ms;
  });
}

PipelineSummary ThesisSystem::summary() const {
  PipelineSummary s;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    s.frontend_dropped = frontend_dropped_;
    s.backend_skipped = backend_skipped_;
  }
  if (joined_) {  // the back-end is the back-end thread's until then
    s.keyframes = backend_.keyframes().size();
    s.loop_closures = backend_.loop_closures();
    s.optimisations = backend_.optimisations();
  }
  return s;
}

std::vector<std::pair<double, Eigen::Isometry3d>> ThesisSystem::final_trajectory() const {
  std::vector<std::pair<double, Eigen::Isometry3d>> out;
  records_->read([&](const std::deque<FrameRecord>& records) {
    for (const auto& r : records) {
      if (!r.ok) continue;
      if (r.backend_processed && r.reference_keyframe >= 0 &&
          backend_.graph().has_node(r.reference_keyframe)) {
        out.emplace_back(r.stamp_s, backend_.keyframe_pose(r.reference_keyframe) * r.T_kf_cam);
      } else {
        out.emplace_back(r.stamp_s, r.T_world_cam);
      }
    }
  });
  return out;
}

}  // namespace rgbdquad::slam
