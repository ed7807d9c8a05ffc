// The pipeline facade; see pipeline.hpp.
#include "slam/pipeline/pipeline.hpp"

namespace rgbdquad::slam {

bool parse_pipeline_mode(const std::string& name, PipelineMode* out, std::string* error) {
  if (name == "sequential") {
    *out = PipelineMode::kSequential;
    return true;
  }
  if (name == "wait") {
    *out = PipelineMode::kWait;
    return true;
  }
  if (name == "realtime") {
    *out = PipelineMode::kRealtime;
    return true;
  }
  if (name == "live") {
    *out = PipelineMode::kLive;
    return true;
  }
  if (error) *error = "unknown mode '" + name + "' (expected wait, realtime, live or sequential)";
  return false;
}

const char* to_string(PipelineMode m) {
  switch (m) {
    case PipelineMode::kSequential:
      return "sequential";
    case PipelineMode::kWait:
      return "wait";
    case PipelineMode::kRealtime:
      return "realtime";
    case PipelineMode::kLive:
      return "live";
  }
  return "?";
}

void PipelineOptions::set_depthless_observations(const std::string& mode) {
  tracker.depthless_observations = mode != "off";
  tracker.depthless_map_points = mode == "map";
  mapper.triangulate_depthless = tracker.depthless_map_points;
}

std::string PipelineOptions::depthless_observations() const {
  if (tracker.depthless_map_points && mapper.triangulate_depthless) return "map";
  return tracker.depthless_observations ? "on" : "off";
}

bool PipelineOptions::is_valid(std::string* error) const {
  if (!frontend.is_valid(error) || !backend.is_valid(error)) return false;
  if (!(checkpoint_period_s >= 0)) {
    if (error) *error = "pipeline: checkpoint_period_s must be >= 0";
    return false;
  }
  if (!checkpoint_path.empty() && backend.kind != BackendKind::kLocalMap) {
    if (error) *error = "pipeline: map checkpoints need the localmap back-end";
    return false;
  }
  if (backend.kind == BackendKind::kLocalMap)
    return tracker.is_valid(error) && mapper.is_valid(error) &&
           (!loop_closing || loop.is_valid(error));
  return true;
}

std::unique_ptr<Pipeline> Pipeline::create(const PipelineOptions& o, const Intrinsics& k,
                                           std::string* error) {
  if (!o.is_valid(error)) return nullptr;
  PipelineOptions opts = o;
  if (o.reprojection_refine) {
    const RansacOptions::Pinhole cam{k.fx_px, k.fy_px, k.cx_px, k.cy_px};
    opts.frontend.ransac.reprojection_camera = cam;
    opts.backend.ransac.reprojection_camera = cam;
  }
  std::unique_ptr<Pipeline> p(new Pipeline());
  if (opts.backend.kind == BackendKind::kLocalMap) {
    p->local_ = LocalMapSystem::create(opts, k, &p->records_, error);
    p->system_ = p->local_.get();
  } else {
    p->thesis_ = ThesisSystem::create(opts, k, &p->records_, error);
    p->system_ = p->thesis_.get();
  }
  if (!p->system_) return nullptr;
  return p;
}

Pipeline::~Pipeline() { finish(); }

bool Pipeline::submit(RgbdFrame frame) {
  if (finished_) return false;
  ++frames_submitted_;
  system_->submit(std::move(frame));
  return true;
}

void Pipeline::finish() {
  if (finished_.exchange(true)) return;
  system_->finish();
  records_.sort_by_index();
}

void Pipeline::retire_records(std::size_t retained, RecordSink sink) {
  records_.retire(retained, std::move(sink));
}

std::vector<FrameRecord> Pipeline::records() const { return records_.sorted(); }

std::optional<FrameRecord> Pipeline::record(std::int64_t index) const {
  return records_.find(index);
}

PipelineSummary Pipeline::summary() const {
  PipelineSummary s = system_->summary();
  s.frames_submitted = frames_submitted_;
  s.frames_failed = records_.failed();
  return s;
}

std::vector<std::pair<double, Eigen::Isometry3d>> Pipeline::final_trajectory() const {
  return system_->final_trajectory();
}

std::vector<MapperStats> Pipeline::mapper_stats() const {
  return local_ ? local_->mapper_stats() : std::vector<MapperStats>{};
}

std::vector<LoopStats> Pipeline::loop_stats() const {
  return local_ ? local_->loop_stats() : std::vector<LoopStats>{};
}

bool Pipeline::load_map(const std::string& path, std::string* error) {
  if (!local_) {
    if (error) *error = "maps are saved and loaded by the localmap back-end only";
    return false;
  }
  return local_->load_map(path, error);
}

bool Pipeline::save_map(const std::string& path, std::string* error) const {
  if (!local_) {
    if (error) *error = "maps are saved and loaded by the localmap back-end only";
    return false;
  }
  return local_->save_map(path, error);
}

}  // namespace rgbdquad::slam
