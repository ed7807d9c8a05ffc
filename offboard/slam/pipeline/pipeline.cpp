// Pipeline threads and hand-over slots; see pipeline.hpp.
#include "slam/pipeline/pipeline.hpp"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>

#include "slam/localmap/map_io.hpp"
#include "slam/pipeline/thread_priority.hpp"

namespace slam {

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
  const bool local_map = o.backend.kind == BackendKind::kLocalMap;
  if (opts.mode == PipelineMode::kLive && !local_map) opts.mode = PipelineMode::kSequential;
  if (o.reprojection_refine) {
    const RansacOptions::Pinhole cam{k.fx_px, k.fy_px, k.cx_px, k.cy_px};
    opts.frontend.ransac.reprojection_camera = cam;
    opts.backend.ransac.reprojection_camera = cam;
  }
  auto fe = FrontEnd::create(opts.frontend, k, error);
  if (!fe) return nullptr;
  auto be = BackEnd::create(opts.backend, error);
  if (!be) return nullptr;
  std::unique_ptr<Pipeline> p(new Pipeline(opts, std::move(*fe), std::move(*be)));
  if (local_map) {
    // Relocalisation matches descriptors and runs RANSAC with the front-end's (thesis) settings.
    TrackerOptions to = opts.tracker;
    to.matching = opts.frontend.matching;
    to.matching.lowe_ratio = to.relocalisation_ratio;
    to.ransac = opts.frontend.ransac;
    CameraModel cam = CameraModel::from(k);
    cam.depth_noise = opts.depth_noise;
    p->camera_ = cam;
    p->extractor_ = FeatureExtractor::create(opts.frontend.features, k, error);
    if (!p->extractor_) return nullptr;
    p->map_ = std::make_shared<SharedMap>(opts.map_lock_priority_inheritance);
    p->tracker_ = Tracker::create(to, cam, p->map_, error);
    if (!p->tracker_) return nullptr;
    p->mapper_ = LocalMapper::create(opts.mapper, cam, p->map_, error);
    if (!p->mapper_) return nullptr;
    if (opts.loop_closing && opts.frontend.features.kind == DetectorKind::kOrb) {
      auto vocabulary = builtin_orb_vocabulary(error);
      if (!vocabulary) return nullptr;
      LoopCloserOptions lo = opts.loop;
      lo.matching = to.matching;
      lo.ransac = to.ransac;
      lo.fit = projection_fit_options(to);
      p->loop_closer_ = LoopCloser::create(
          lo, cam, p->map_, std::make_shared<const BinaryVocabulary>(std::move(*vocabulary)),
          error);
      if (!p->loop_closer_) return nullptr;
      p->summary_.loop_closing_active = true;
    }
  }
  if (opts.mode == PipelineMode::kLive) {
    p->backend_thread_ = std::thread([q = p.get()] { q->mapper_loop(); });
  } else if (opts.mode != PipelineMode::kSequential) {
    p->frontend_thread_ = std::thread([q = p.get()] { q->frontend_loop(); });
    if (local_map)
      p->backend_thread_ = std::thread([q = p.get()] { q->mapper_loop(); });
    else
      p->backend_thread_ = std::thread([q = p.get()] { q->backend_loop(); });
  }
  if (p->loop_closer_ && opts.mode != PipelineMode::kSequential)
    p->loop_thread_ = std::thread([q = p.get()] { q->loop_closing_loop(); });
  return p;
}

Pipeline::Pipeline(PipelineOptions options, FrontEnd frontend, BackEnd backend)
    : options_(std::move(options)), frontend_(std::move(frontend)), backend_(std::move(backend)) {}

Pipeline::~Pipeline() { finish(); }

bool Pipeline::submit(RgbdFrame frame) {
  if (finished_) return false;
  if (options_.mode == PipelineMode::kSequential || options_.mode == PipelineMode::kLive) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++summary_.frames_submitted;
    }
    run_frontend(frame);
    return true;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  ++summary_.frames_submitted;
  if (options_.mode == PipelineMode::kRealtime) {
    if (!input_.empty()) {
      ++summary_.frontend_dropped;
      input_.clear();
    }
  } else {
    cv_.wait(lock, [&] { return input_.empty(); });
  }
  input_.push_back(std::move(frame));
  cv_.notify_all();
  return true;
}

void Pipeline::finish() {
  if (finished_.exchange(true)) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    input_closed_ = true;
  }
  cv_.notify_all();
  if (frontend_thread_.joinable()) frontend_thread_.join();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    handover_closed_ = true;
    keyframes_closed_ = true;
  }
  cv_.notify_all();
  if (backend_thread_.joinable()) backend_thread_.join();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    loop_closed_ = true;
  }
  cv_.notify_all();
  if (loop_thread_.joinable()) loop_thread_.join();
  checkpoint_if_due(/*force=*/true);
  std::sort(records_.begin(), records_.end(),
            [](const FrameRecord& a, const FrameRecord& b) { return a.index < b.index; });
  if (is_local_map()) {
    std::lock_guard<MapMutex> lock(map_->mutex);
    summary_.keyframes = map_->map.keyframes().size();
    summary_.map_points = map_->map.points().size();
    summary_.keyframes_culled = map_->map.culled().size();
    summary_.loop_closures = map_->map.loop_edges().size();
    for (const LoopStats& l : loop_stats_) summary_.loop_detections += l.candidates > 0 ? 1 : 0;
  } else {
    summary_.keyframes = backend_->keyframes().size();
    summary_.loop_closures = backend_->loop_closures();
    summary_.optimisations = backend_->optimisations();
  }
}

void Pipeline::retire_records(std::size_t retained, RecordSink sink) {
  std::lock_guard<std::mutex> lock(mutex_);
  retained_records_ = std::max<std::size_t>(retained, 1);
  record_sink_ = std::move(sink);
}

void Pipeline::push_record_locked(FrameRecord rec) {
  if (!rec.ok) ++summary_.frames_failed;
  records_.push_back(std::move(rec));
  while (retained_records_ > 0 && records_.size() > retained_records_) {
    retired_.push_back(std::move(records_.front()));
    records_.pop_front();
  }
}

void Pipeline::hand_retired() {
  std::vector<FrameRecord> retired;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    retired.swap(retired_);
  }
  if (record_sink_)
    for (const FrameRecord& r : retired) record_sink_(r);
}

void Pipeline::frontend_loop() {
  name_current_thread("slam-tracking");
  if (options_.mode == PipelineMode::kRealtime &&
      options_.tracking_thread_policy != ThreadPolicy::kOff) {
    ThreadPriorityOptions tp;
    tp.policy = options_.tracking_thread_policy;
    const ThreadPriorityResult r = raise_current_thread(tp);
    std::lock_guard<std::mutex> lock(mutex_);
    summary_.tracking_thread = r.describe("tracking");
  }
  for (;;) {
    RgbdFrame frame;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return !input_.empty() || input_closed_; });
      if (input_.empty()) return;
      frame = std::move(input_.front());
      input_.pop_front();
    }
    cv_.notify_all();
    run_frontend(frame);
  }
}

void Pipeline::backend_loop() {
  name_current_thread("slam-backend");
  if (options_.mode == PipelineMode::kRealtime) {
    // Real time: the front-end must keep up with the camera; the back-end is best effort (it
    // skips frames anyway), so it yields the CPU to the front-end. Linux applies nice per thread.
    // Below the front-end either way (slam/pipeline/thread_priority.hpp): by weight under a normal
    // front-end, by policy under a real-time one (then still ahead of the machine's other work).
    // Not fatal when refused: the back-end then competes for the CPU as an equal.
    constexpr int kBackendNiceRealtime = 10;
    constexpr int kBackendNiceBelowRealtime = -10;
    lower_current_thread(kBackendNiceRealtime, kBackendNiceBelowRealtime);
  }
  for (;;) {
    FrontendOutput out;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return !handover_.empty() || handover_closed_; });
      if (handover_.empty()) return;
      out = std::move(handover_.front());
      handover_.pop_front();
    }
    cv_.notify_all();
    run_backend(out);
  }
}

void Pipeline::run_frontend(const RgbdFrame& frame) {
  if (is_local_map()) {
    run_tracker(frame);
    return;
  }
  std::string error;
  std::optional<FrontendOutput> out;
  try {
    out = frontend_->process(frame, &error);
  } catch (const std::exception& e) {  // nothing escapes a thread
    error = std::string("front-end exception: ") + e.what();
  }
  FrameRecord rec;
  rec.index = frame.index;
  rec.stamp_s = frame.stamp_s;
  if (!out) {
    rec.ok = false;
    rec.error = error;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      push_record_locked(std::move(rec));
    }
    hand_retired();
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
    std::lock_guard<std::mutex> lock(mutex_);
    rec.T_world_cam = correction_ * out->T_odom_cam;  // replaced when the back-end processes it
    rec.map_corrections = backend_loop_corrections_;
    push_record_locked(std::move(rec));
  }
  hand_retired();
  if (options_.mode == PipelineMode::kSequential) {
    run_backend(*out);
    return;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  if (options_.mode == PipelineMode::kRealtime) {
    if (!handover_.empty()) {
      ++summary_.backend_skipped;
      handover_.clear();
    }
  } else {
    cv_.wait(lock, [&] { return handover_.empty(); });
  }
  handover_.push_back(std::move(*out));
  cv_.notify_all();
}

void Pipeline::run_backend(const FrontendOutput& in) {
  BackendOutput out;
  try {
    out = backend_->process(in);
  } catch (const std::exception&) {  // nothing escapes a thread; the frame keeps its VO pose
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  correction_ = out.T_world_cam * in.T_odom_cam.inverse();
  if (out.loop_closed) ++backend_loop_corrections_;
  for (auto it = records_.rbegin(); it != records_.rend(); ++it) {
    if (it->index != in.index) continue;
    it->backend_processed = true;
    it->keyframe = out.keyframe;
    it->llc_applied = out.llc_applied;
    it->loop_closed = out.loop_closed;
    it->reference_keyframe = out.reference_keyframe;
    it->T_world_cam = out.T_world_cam;
    it->T_kf_cam = out.T_kf_cam;
    it->map_corrections = backend_loop_corrections_;
    it->keyframe_ms = out.keyframe_ms;
    it->llc_ms = out.llc_ms;
    it->glc_ms = out.glc_ms;
    it->posegraph_ms = out.posegraph_ms;
    it->backend_ms = out.total_ms;
    it->backend_cpu_ms = out.total_cpu_ms;
    break;
  }
}

std::vector<FrameRecord> Pipeline::records() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return {records_.begin(), records_.end()};
}

std::optional<FrameRecord> Pipeline::record(std::int64_t index) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = records_.rbegin(); it != records_.rend(); ++it)
    if (it->index == index) return *it;
  return std::nullopt;
}

PipelineSummary Pipeline::summary() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return summary_;
}

bool Pipeline::load_map(const std::string& path, std::string* error) {
  if (!is_local_map()) {
    if (error) *error = "maps are saved and loaded by the localmap back-end only";
    return false;
  }
  std::uint64_t corrections = 0;
  auto loaded = slam::load_map(path, map_file_context(), error, &corrections);
  if (!loaded) return false;
  {
    std::lock_guard<MapMutex> lock(map_->mutex);
    if (!map_->map.keyframes().empty()) {
      if (error) *error = "load_map: the pipeline has already started a map";
      return false;
    }
    map_->map = std::move(*loaded);
    map_->corrections = corrections;  // the world frame's revision goes on from the file's
  }
  tracker_->set_lost();  // the first frames relocalise in the loaded map
  if (loop_closer_) loop_closer_->index_map();
  return true;
}

bool Pipeline::save_map(const std::string& path, std::string* error) const {
  if (!is_local_map()) {
    if (error) *error = "maps are saved and loaded by the localmap back-end only";
    return false;
  }
  std::lock_guard<MapMutex> lock(map_->mutex);
  return slam::save_map(path, map_->map, map_file_context(), error, map_->corrections);
}

MapFileContext Pipeline::map_file_context() const {
  return MapFileContext{camera_, options_.frontend.features};
}

void Pipeline::checkpoint_if_due(bool force) {
  if (options_.checkpoint_path.empty() || !is_local_map()) return;
  std::lock_guard<std::mutex> writer(checkpoint_mutex_);
  const std::int64_t t0 = steady_now_ns();
  SlamMap copy;
  std::uint64_t corrections = 0;
  double stamp_s = 0;
  {
    std::lock_guard<MapMutex> lock(map_->mutex);
    if (map_->map.keyframes().empty()) return;
    stamp_s = map_->map.keyframes().rbegin()->second.stamp_s;
    corrections = map_->corrections;
    // Due when a newer keyframe is `checkpoint_period_s` past the last checkpoint's newest, or a
    // loop correction moved the map since; a map without new keyframes is not rewritten.
    const bool due = !checkpoint_stamp_s_ ||
                     (stamp_s > *checkpoint_stamp_s_ &&
                      stamp_s - *checkpoint_stamp_s_ >= options_.checkpoint_period_s) ||
                     corrections != checkpoint_corrections_;
    if (!due && !force) return;
    copy = map_->map;  // keyframe features and descriptors are shared, never written in place
  }
  std::string error;
  const bool ok =
      slam::save_map(options_.checkpoint_path, copy, map_file_context(), &error, corrections);
  const double ms = ms_since(t0);
  checkpoint_stamp_s_ = stamp_s;
  checkpoint_corrections_ = corrections;
  std::lock_guard<std::mutex> lock(mutex_);
  if (ok) {
    ++summary_.checkpoints_written;
    summary_.checkpoint_max_ms = std::max(summary_.checkpoint_max_ms, ms);
  } else {
    summary_.checkpoint_error = error;
  }
}

std::vector<MapperStats> Pipeline::mapper_stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return mapper_stats_;
}

std::vector<LoopStats> Pipeline::loop_stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return loop_stats_;
}

void Pipeline::close_loops(std::int64_t kf) {
  LoopStats st;
  try {
    st = loop_closer_->process(kf);
  } catch (const std::exception&) {  // nothing escapes a thread; the map stays as mapped
    st.keyframe = kf;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  loop_stats_.push_back(st);
}

void Pipeline::loop_closing_loop() {
  name_current_thread("slam-loop");
  if (paced()) {
    // Off the camera-to-command path and, unlike mapping, not needed by the next frames: the
    // normal policy below tracking (place_mapping_thread's fallback nices).
    constexpr int kLoopClosingNiceRealtime = 10;
    constexpr int kLoopClosingNiceBelowRealtime = -10;
    lower_current_thread(kLoopClosingNiceRealtime, kLoopClosingNiceBelowRealtime);
  }
  for (;;) {
    std::int64_t kf;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return !loop_queue_.empty() || loop_closed_; });
      if (loop_queue_.empty()) return;
      kf = loop_queue_.front();
      loop_queue_.pop_front();
      loop_busy_ = true;
    }
    close_loops(kf);
    checkpoint_if_due(/*force=*/false);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      loop_busy_ = false;
    }
    cv_.notify_all();
  }
}

KeyframeAdmission keyframe_admission(std::size_t keyframes_in_mapper, bool gate_on_busy_mapper) {
  KeyframeAdmission a;
  a.allowed = keyframes_in_mapper < kMaxQueuedKeyframesWeak;
  a.mapper_idle = keyframes_in_mapper < kMaxQueuedKeyframes &&
                  (!gate_on_busy_mapper || keyframes_in_mapper == 0);
  return a;
}

void Pipeline::run_tracker(const RgbdFrame& frame) {
  const std::int64_t t0 = steady_now_ns();
  const std::int64_t c0 = thread_cpu_now_ns();
  FrameRecord rec;
  rec.index = frame.index;
  rec.stamp_s = frame.stamp_s;
  std::string error;
  std::optional<FrameFeatures> feats;
  try {
    feats = extractor_->extract(frame, &error);
  } catch (const std::exception& e) {  // nothing escapes a thread
    error = std::string("features: exception: ") + e.what();
  }
  if (!feats) {
    rec.ok = false;
    rec.error = error;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      push_record_locked(std::move(rec));
    }
    hand_retired();
    return;
  }
  rec.features_ms = ms_since(t0);
  rec.features = feats->points_cam_m.size();
  bool keyframe_allowed = true,
       mapper_idle = true;  // wait/sequential: mapping is done before the next frame
  if (paced()) {
    std::lock_guard<std::mutex> lock(mutex_);
    const KeyframeAdmission admission = keyframe_admission(
        keyframe_queue_.size() + (mapper_busy_ ? 1 : 0), options_.keyframe_gate_mapper_busy);
    keyframe_allowed = admission.allowed;
    mapper_idle = admission.mapper_idle;
  }
  TrackResult tr;
  try {
    tr = tracker_->track(frame, std::make_shared<const FrameFeatures>(std::move(*feats)),
                         extractor_->options(), keyframe_allowed, mapper_idle);
  } catch (const std::exception& e) {
    tr.state = TrackingState::kLost;
    error = std::string("tracker: exception: ") + e.what();
  }
  rec.ok = true;
  rec.error = error;
  rec.state = tr.state;
  rec.backend_processed = tr.state == TrackingState::kTracking;
  rec.keyframe = tr.keyframe;
  rec.reference_keyframe = tr.reference_keyframe;
  rec.T_world_cam = tr.T_world_cam;
  rec.T_kf_cam = tr.T_kf_cam;
  rec.matches = tr.matches;
  rec.inliers = tr.inliers;
  rec.map_keyframes = tr.map_keyframes;
  rec.map_points = tr.map_points;
  rec.keyframe_wanted = tr.keyframe_wanted;
  rec.ref_tracked = tr.ref_tracked;
  rec.near_tracked = tr.near_tracked;
  rec.near_untracked = tr.near_untracked;
  rec.near_redundant = tr.near_redundant;
  rec.matching_ms = tr.local_map_ms + tr.search_ms;
  rec.ransac_ms = tr.relocalise_ms;
  rec.relocalised = tr.relocalised;
  rec.cross_checked = tr.cross_checked;
  rec.cross_check_shift_m = tr.cross_check_shift_m;
  rec.cross_check_shift_deg = tr.cross_check_shift_deg;
  rec.prediction_stale = tr.prediction_stale;
  rec.attitude_predicted = tr.attitude_predicted;
  rec.prediction_deviation_m = tr.prediction_deviation_m;
  rec.prediction_deviation_bound_m = tr.prediction_deviation_bound_m;
  rec.map_lock_wait_ms = tr.map_lock_wait_ms;
  rec.map_corrections = tr.map_corrections;
  rec.frontend_ms = ms_since(t0);
  rec.frontend_cpu_ms = (thread_cpu_now_ns() - c0) * 1e-6;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (tr.relocalised && !tr.cross_checked) ++summary_.relocalisations;
    if (tr.cross_checked) ++summary_.cross_checks;
    if (tr.relocalised && tr.cross_checked) ++summary_.cross_check_replacements;
    if (tr.state == TrackingState::kLost) ++summary_.frames_lost;
    push_record_locked(std::move(rec));
  }
  hand_retired();
  if (!tr.keyframe) return;
  if (options_.mode == PipelineMode::kSequential) {
    const MapperStats st = mapper_->process(tr.keyframe_id);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      mapper_stats_.push_back(st);
    }
    if (loop_closer_) close_loops(tr.keyframe_id);
    checkpoint_if_due(/*force=*/false);
    return;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  keyframe_queue_.push_back(tr.keyframe_id);
  cv_.notify_all();
  if (options_.mode == PipelineMode::kWait)
    cv_.wait(lock, [&] {
      return keyframe_queue_.empty() && !mapper_busy_ && loop_queue_.empty() && !loop_busy_;
    });
}

void Pipeline::mapper_loop() {
  name_current_thread("slam-mapping");
  const bool realtime = paced();
  if (realtime) {
    const std::string applied = place_mapping_thread().describe("mapping");
    std::lock_guard<std::mutex> lock(mutex_);
    summary_.mapping_thread = applied;
  }
  // Realtime: a mapper that falls behind leaves fusion and the BA to the newest keyframe.
  LocalMapper::KeyframesWaiting waiting;
  if (realtime)
    waiting = [this] {
      std::lock_guard<std::mutex> lock(mutex_);
      return !keyframe_queue_.empty();
    };
  for (;;) {
    std::int64_t kf;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return !keyframe_queue_.empty() || keyframes_closed_; });
      if (keyframe_queue_.empty()) return;
      kf = keyframe_queue_.front();
      keyframe_queue_.pop_front();
      mapper_busy_ = true;
    }
    MapperStats st;
    try {
      st = mapper_->process(kf, waiting);
    } catch (const std::exception&) {  // nothing escapes a thread; the keyframe stays as tracked
      st.keyframe = kf;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      summary_.mapper_caught_up += st.caught_up ? 1 : 0;
      summary_.mapper_ba_interrupted += st.ba_interrupted ? 1 : 0;
      mapper_stats_.push_back(st);
      mapper_busy_ = false;
      if (loop_closer_)
        loop_queue_.push_back(kf);  // same step: wait mode never sees both idle early
    }
    cv_.notify_all();
    if (!loop_closer_) checkpoint_if_due(/*force=*/false);  // else after its loop closing
  }
}

ThreadPriorityResult Pipeline::place_mapping_thread() const {
  // Real-time tracking: SCHED_RR below it (PipelineOptions::mapping_rt_priority says why).
  const bool tracking_realtime = (options_.mode == PipelineMode::kRealtime &&
                                  (options_.tracking_thread_policy == ThreadPolicy::kRoundRobin ||
                                   options_.tracking_thread_policy == ThreadPolicy::kFifo)) ||
                                 current_thread_is_realtime();
  // Otherwise, or when the OS refuses: the normal policy below its creator - by weight under a
  // normal tracker; under a real-time one at nice -10, still ahead of the process's other work
  // (at nice 10 beside two CPU burners mapping starved and tracking was lost in the HIL take-off).
  constexpr int kMapperNiceRealtime = 10;
  constexpr int kMapperNiceBelowRealtime = -10;
  if (tracking_realtime && options_.mapping_rt_priority > 0) {
    ThreadPriorityOptions rr;
    rr.policy = ThreadPolicy::kRoundRobin;
    rr.rt_priority = options_.mapping_rt_priority;
    const ThreadSchedule before = current_thread_schedule();
    ThreadPriorityResult r = raise_current_thread(rr);
    if (r.realtime) return r;
    restore_current_thread(before);  // raise_current_thread fell back to its own nice
    ThreadPriorityResult lowered =
        lower_current_thread(kMapperNiceRealtime, kMapperNiceBelowRealtime);
    lowered.reason = r.reason + (lowered.reason.empty() ? "" : "; " + lowered.reason);
    return lowered;
  }
  return lower_current_thread(kMapperNiceRealtime, kMapperNiceBelowRealtime);
}

std::vector<std::pair<double, Eigen::Isometry3d>> Pipeline::final_trajectory() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::pair<double, Eigen::Isometry3d>> out;
  if (is_local_map()) {
    // Each tracked frame re-anchored to the final pose of its reference keyframe.
    std::lock_guard<MapMutex> map_lock(map_->mutex);
    for (const auto& r : records_) {
      if (!r.ok) continue;
      const auto T_kf =
          r.reference_keyframe >= 0 ? map_->map.resolve_pose(r.reference_keyframe) : std::nullopt;
      out.emplace_back(r.stamp_s, T_kf && r.state == TrackingState::kTracking ? *T_kf * r.T_kf_cam
                                                                              : r.T_world_cam);
    }
    return out;
  }
  for (const auto& r : records_) {
    if (!r.ok) continue;
    if (r.backend_processed && r.reference_keyframe >= 0 &&
        backend_->graph().has_node(r.reference_keyframe)) {
      out.emplace_back(r.stamp_s, backend_->keyframe_pose(r.reference_keyframe) * r.T_kf_cam);
    } else {
      out.emplace_back(r.stamp_s, r.T_world_cam);
    }
  }
  return out;
}

}  // namespace slam
