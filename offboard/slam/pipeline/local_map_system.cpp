// The local-map system's three stages; see local_map_system.hpp.
#include "slam/pipeline/local_map_system.hpp"

#include "slam/loopclosing/vocabulary.hpp"
#include "slam/map/map_io.hpp"
#include "slam/tracking/depth_time_alignment.hpp"

namespace rgbdquad::slam {

namespace {

// Off the camera-to-command path, mapping and loop closing run below tracking. Linux applies nice
// per thread: nice 10 under a normal creator; under a real-time one -10, still ahead of the
// machine's other work (at nice 10 beside two CPU burners mapping starved and tracking was lost
// in the HIL take-off).
constexpr int kBelowTrackingNice = 10;
constexpr int kBelowRealtimeTrackingNice = -10;

/// The record of a frame the tracker handled.
FrameRecord record_of(const RgbdFrame& frame, const TrackResult& tr) {
  FrameRecord rec;
  rec.index = frame.index;
  rec.stamp_s = frame.stamp_s;
  rec.ok = true;
  rec.state = tr.state;
  rec.backend_processed = tr.state == TrackingState::kTracking;
  rec.keyframe = tr.keyframe;
  rec.reference_keyframe = tr.reference_keyframe;
  rec.T_world_cam = tr.T_world_cam;
  rec.T_kf_cam = tr.T_kf_cam;
  rec.matches = tr.matches;
  rec.inliers = tr.inliers;
  rec.depthless_inliers = tr.depthless_inliers;
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
  rec.new_segment = tr.new_segment;
  rec.segment_merged = tr.segment_merged;
  rec.off_path_confirmed = tr.off_path_confirmed;
  rec.attitude_refused = tr.attitude_refused;
  rec.gravity_prior = tr.gravity_prior;
  if (const auto& w = tr.rolling_shutter_rate_rad_per_s)
    rec.rolling_shutter_rate_rad_per_s = std::array<double, 3>{w->x(), w->y(), w->z()};
  rec.cross_check_shift_m = tr.cross_check_shift_m;
  rec.cross_check_shift_deg = tr.cross_check_shift_deg;
  rec.prediction_stale = tr.prediction_stale;
  rec.attitude_predicted = tr.attitude_predicted;
  rec.prediction_deviation_m = tr.prediction_deviation_m;
  rec.prediction_deviation_bound_m = tr.prediction_deviation_bound_m;
  rec.map_lock_wait_ms = tr.map_lock_wait_ms;
  rec.map_corrections = tr.map_corrections;
  return rec;
}

}  // namespace

KeyframeAdmission keyframe_admission(std::size_t keyframes_in_mapper, bool gate_on_busy_mapper) {
  KeyframeAdmission a;
  a.allowed = keyframes_in_mapper < kMaxQueuedKeyframesWeak;
  a.segment_start_allowed = keyframes_in_mapper < kMaxQueuedKeyframesSegmentStart;
  a.mapper_idle = keyframes_in_mapper < kMaxQueuedKeyframes &&
                  (!gate_on_busy_mapper || keyframes_in_mapper == 0);
  return a;
}

// ---------------------------------------------------------------------------------------------
// Loop closing.

LoopClosingStage::LoopClosingStage(LoopCloser closer, StagePacing pacing,
                                   std::function<void()> after_keyframe)
    : closer_(std::move(closer)), pacing_(pacing), after_keyframe_(std::move(after_keyframe)) {}

void LoopClosingStage::start() {
  if (pacing_.mode != PipelineMode::kSequential) thread_ = std::thread([this] { run(); });
}

void LoopClosingStage::submit(std::int64_t kf) {
  if (pacing_.mode == PipelineMode::kSequential) {
    close(kf);
    return;
  }
  queue_.push(kf);
}

LoopStats LoopClosingStage::process(std::int64_t kf) {
  try {
    return closer_.process(kf);
  } catch (const std::exception&) {  // nothing escapes a thread; the map stays as mapped
    LoopStats st;
    st.keyframe = kf;
    return st;
  }
}

void LoopClosingStage::close(std::int64_t kf) {
  const LoopStats st = process(kf);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.push_back(st);
  }
  after_keyframe_();
}

void LoopClosingStage::run() {
  name_current_thread("slam-loop");
  // Unlike mapping, not needed by the next frames: the normal policy below tracking.
  if (pacing_.paced()) lower_current_thread(kBelowTrackingNice, kBelowRealtimeTrackingNice);
  drain_stage_queue(queue_, [this](std::int64_t kf) { close(kf); });
}

void LoopClosingStage::finish() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
}

std::vector<LoopStats> LoopClosingStage::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

// ---------------------------------------------------------------------------------------------
// Map checkpoints.

CheckpointStage::CheckpointStage(MapCheckpointer* checkpointer, StagePacing pacing)
    : checkpointer_(checkpointer), pacing_(pacing) {}

void CheckpointStage::start() {
  if (pacing_.mode == PipelineMode::kSequential) return;
  thread_ = std::thread([this] {
    name_current_thread("slam-checkpoint");
    // Off every real-time path, like loop closing.
    if (pacing_.paced()) lower_current_thread(kBelowTrackingNice, kBelowRealtimeTrackingNice);
    drain_stage_queue(queue_, [this](double now_s) { checkpointer_->write(now_s); });
  });
}

void CheckpointStage::request(double now_s) {
  if (pacing_.mode == PipelineMode::kSequential) {
    checkpointer_->write(now_s);
    return;
  }
  queue_.push_replacing(now_s);
}

void CheckpointStage::finish() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
}

// ---------------------------------------------------------------------------------------------
// Local mapping.

LocalMappingStage::LocalMappingStage(LocalMapper mapper, StagePacing pacing,
                                     std::function<void(std::int64_t)> after_keyframe)
    : mapper_(std::move(mapper)), pacing_(pacing), after_keyframe_(std::move(after_keyframe)) {}

void LocalMappingStage::start() {
  if (pacing_.mode != PipelineMode::kSequential) thread_ = std::thread([this] { run(); });
}

void LocalMappingStage::submit(std::int64_t kf) {
  if (pacing_.mode == PipelineMode::kSequential) {
    map(kf, {});
    return;
  }
  queue_.push(kf);
}

MapperStats LocalMappingStage::process(std::int64_t kf,
                                       const LocalMapper::KeyframesWaiting& waiting) {
  try {
    return mapper_.process(kf, waiting);
  } catch (const std::exception&) {  // nothing escapes a thread; the keyframe stays as tracked
    MapperStats st;
    st.keyframe = kf;
    return st;
  }
}

void LocalMappingStage::map(std::int64_t kf, const LocalMapper::KeyframesWaiting& waiting) {
  const MapperStats st = process(kf, waiting);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    caught_up_ += st.caught_up ? 1 : 0;
    ba_interrupted_ += st.ba_interrupted ? 1 : 0;
    stats_.push_back(st);
  }
  after_keyframe_(kf);
}

void LocalMappingStage::run() {
  name_current_thread("slam-mapping");
  LocalMapper::KeyframesWaiting waiting;
  if (pacing_.paced()) {
    const std::string applied = place_thread().describe("mapping");
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      thread_description_ = applied;
    }
    // A mapper that falls behind leaves fusion and the BA to the newest keyframe.
    waiting = [this] {
      const bool live = queue_.has_waiting();
      return pacing_.schedule ? pacing_.schedule->answer(MapParty::kMapping, live) != 0 : live;
    };
  }
  drain_stage_queue(queue_, [&](std::int64_t kf) { map(kf, waiting); });
}

ThreadPriorityResult LocalMappingStage::place_thread() const {
  // Real-time tracking: SCHED_RR below it (PipelineOptions::mapping_rt_priority says why).
  const bool tracking_realtime = (pacing_.mode == PipelineMode::kRealtime &&
                                  (pacing_.tracking_thread_policy == ThreadPolicy::kRoundRobin ||
                                   pacing_.tracking_thread_policy == ThreadPolicy::kFifo)) ||
                                 current_thread_is_realtime();
  if (tracking_realtime && pacing_.mapping_rt_priority > 0) {
    ThreadPriorityOptions rr;
    rr.policy = ThreadPolicy::kRoundRobin;
    rr.rt_priority = pacing_.mapping_rt_priority;
    const ThreadSchedule before = current_thread_schedule();
    ThreadPriorityResult r = raise_current_thread(rr);
    if (r.realtime) return r;
    restore_current_thread(before);  // raise_current_thread fell back to its own nice
    ThreadPriorityResult lowered =
        lower_current_thread(kBelowTrackingNice, kBelowRealtimeTrackingNice);
    lowered.reason = r.reason + (lowered.reason.empty() ? "" : "; " + lowered.reason);
    return lowered;
  }
  return lower_current_thread(kBelowTrackingNice, kBelowRealtimeTrackingNice);
}

void LocalMappingStage::finish() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
}

std::vector<MapperStats> LocalMappingStage::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

void LocalMappingStage::add_to(PipelineSummary* s) const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  s->mapping_thread = thread_description_;
  s->mapper_caught_up = caught_up_;
  s->mapper_ba_interrupted = ba_interrupted_;
}

// ---------------------------------------------------------------------------------------------
// Tracking.

TrackingStage::TrackingStage(FeatureExtractor extractor, Tracker tracker, StagePacing pacing,
                             std::function<KeyframeAdmission()> admission, FrameRecords* records,
                             std::function<void(std::int64_t)> on_keyframe,
                             const Intrinsics& intrinsics, bool align_depth_time,
                             double colour_stamp_lag_s)
    : extractor_(std::move(extractor)),
      tracker_(std::move(tracker)),
      intrinsics_(intrinsics),
      align_depth_time_(align_depth_time),
      colour_stamp_lag_s_(colour_stamp_lag_s),
      pacing_(pacing),
      admission_(std::move(admission)),
      records_(records),
      on_keyframe_(std::move(on_keyframe)) {}

void TrackingStage::start() {
  if (pacing_.mode == PipelineMode::kWait || pacing_.mode == PipelineMode::kRealtime)
    thread_ = std::thread([this] { run(); });
}

void TrackingStage::submit(RgbdFrame frame) {
  switch (pacing_.mode) {
    case PipelineMode::kSequential:
    case PipelineMode::kLive:
      track(frame);
      return;
    case PipelineMode::kWait:
      queue_.push_waiting(std::move(frame));
      return;
    case PipelineMode::kRealtime: {
      const std::size_t dropped = queue_.push_replacing(std::move(frame));
      std::lock_guard<std::mutex> lock(counts_mutex_);
      counts_.frontend_dropped += dropped;
      return;
    }
  }
}

void TrackingStage::run() {
  name_current_thread("slam-tracking");
  if (pacing_.mode == PipelineMode::kRealtime &&
      pacing_.tracking_thread_policy != ThreadPolicy::kOff) {
    ThreadPriorityOptions tp;
    tp.policy = pacing_.tracking_thread_policy;
    const ThreadPriorityResult r = raise_current_thread(tp);
    std::lock_guard<std::mutex> lock(counts_mutex_);
    counts_.tracking_thread = r.describe("tracking");
  }
  drain_stage_queue(queue_, [this](const RgbdFrame& frame) { track(frame); });
}

TrackingStage::Output TrackingStage::process(const RgbdFrame& frame, KeyframeAdmission admission) {
  const std::int64_t t0 = steady_now_ns();
  const std::int64_t c0 = thread_cpu_now_ns();
  Output out;
  std::string error;
  std::optional<FrameFeatures> feats;
  try {
    feats = extractor_.extract(depth_aligned(frame), &error);
  } catch (const std::exception& e) {  // nothing escapes a thread
    error = std::string("features: exception: ") + e.what();
  }
  if (!feats) {
    out.record.index = frame.index;
    out.record.stamp_s = frame.stamp_s;
    out.record.ok = false;
    out.record.error = error;
    return out;
  }
  const double features_ms = ms_since(t0);
  const std::size_t features = feats->points_cam_m.size();
  TrackResult tr;
  try {
    tr = tracker_.track(frame, std::make_shared<const FrameFeatures>(std::move(*feats)),
                        extractor_.options(), admission);
  } catch (const std::exception& e) {
    tr.state = TrackingState::kLost;
    error = std::string("tracker: exception: ") + e.what();
  }
  out.record = record_of(frame, tr);
  out.record.error = error;
  out.record.features_ms = features_ms;
  out.record.features = features;
  out.record.frontend_ms = ms_since(t0);
  out.record.frontend_cpu_ms = (thread_cpu_now_ns() - c0) * 1e-6;
  if (tr.keyframe) out.keyframe = tr.keyframe_id;
  return out;
}

RgbdFrame TrackingStage::depth_aligned(const RgbdFrame& frame) const {
  if (!align_depth_time_ || !frame.depth_stamp_s) return frame;
  const auto omega = tracker_.predicted_rotation_rate_rad_per_s();
  if (!omega) return frame;
  RgbdFrame out = frame;  // images are shared; only the depth is replaced
  const double colour_exposure_s = frame.stamp_s - colour_stamp_lag_s_;
  out.depth = align_depth_to_colour_time(frame.depth, intrinsics_, *omega,
                                         colour_exposure_s - *frame.depth_stamp_s);
  return out;
}

void TrackingStage::track(const RgbdFrame& frame) {
  if (pacing_.schedule) pacing_.schedule->frame(frame.stamp_s);
  // Sequential and wait modes: mapping is done before the next frame.
  const KeyframeAdmission admission = pacing_.paced() ? admission_() : KeyframeAdmission{};
  Output out = process(frame, admission);
  if (out.record.ok) {
    const FrameRecord& r = out.record;
    std::lock_guard<std::mutex> lock(counts_mutex_);
    if (r.relocalised && !r.cross_checked) ++counts_.relocalisations;
    if (r.cross_checked) ++counts_.cross_checks;
    if (r.relocalised && r.cross_checked) ++counts_.cross_check_replacements;
    if (r.state == TrackingState::kLost) ++counts_.frames_lost;
    if (r.new_segment) ++counts_.segments_started;
    if (r.segment_merged) ++counts_.segments_merged;
    if (r.off_path_confirmed) ++counts_.off_path_confirmed;
    if (r.attitude_refused) ++counts_.attitude_refusals;
    if (r.gravity_prior) ++counts_.gravity_frames;
  }
  records_->add(std::move(out.record));
  if (out.keyframe) on_keyframe_(*out.keyframe);
}

void TrackingStage::finish() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
}

void TrackingStage::add_to(PipelineSummary* s) const {
  std::lock_guard<std::mutex> lock(counts_mutex_);
  s->frontend_dropped = counts_.frontend_dropped;
  s->tracking_thread = counts_.tracking_thread;
  s->relocalisations = counts_.relocalisations;
  s->cross_checks = counts_.cross_checks;
  s->cross_check_replacements = counts_.cross_check_replacements;
  s->frames_lost = counts_.frames_lost;
  s->segments_started = counts_.segments_started;
  s->segments_merged = counts_.segments_merged;
  s->off_path_confirmed = counts_.off_path_confirmed;
  s->attitude_refusals = counts_.attitude_refusals;
  s->gravity_frames = counts_.gravity_frames;
}

// ---------------------------------------------------------------------------------------------
// The system.

LocalMapSystem::LocalMapSystem(const PipelineOptions& options, CameraModel camera,
                               FrameRecords* records)
    : options_(options),
      camera_(camera),
      records_(records),
      map_(std::make_shared<SharedMap>(options.map_lock_priority_inheritance)) {}

std::unique_ptr<LocalMapSystem> LocalMapSystem::create(const PipelineOptions& opts,
                                                       const Intrinsics& k, FrameRecords* records,
                                                       std::string* error) {
  // Relocalisation matches descriptors and runs RANSAC with the front-end's (thesis) settings.
  TrackerOptions to = opts.tracker;
  to.matching = opts.frontend.matching;
  to.matching.lowe_ratio = to.relocalisation_ratio;
  to.ransac = opts.frontend.ransac;
  CameraModel cam = CameraModel::from(k);
  cam.depth_noise = opts.depth_noise;
  std::unique_ptr<LocalMapSystem> s(new LocalMapSystem(opts, cam, records));
  if (!s->open_lock_schedule(error)) return nullptr;
  const StagePacing pacing{opts.mode, opts.tracking_thread_policy, opts.mapping_rt_priority,
                           s->map_->schedule};

  FeatureOptions features = opts.frontend.features;
  features.orb_spread_oversample = opts.local_map_orb_spread_oversample;
  auto extractor = FeatureExtractor::create(features, k, error);
  if (!extractor) return nullptr;
  auto tracker = Tracker::create(to, cam, s->map_, error);
  if (!tracker) return nullptr;
  LocalMapperOptions mo = opts.mapper;
  mo.triangulation.scale_factor = features.orb_scale_factor;
  auto mapper = LocalMapper::create(mo, cam, s->map_, error);
  if (!mapper) return nullptr;
  std::optional<LoopCloser> closer;
  if (opts.loop_closing && opts.frontend.features.kind == DetectorKind::kOrb) {
    auto vocabulary = builtin_orb_vocabulary(error);
    if (!vocabulary) return nullptr;
    LoopCloserOptions lo = opts.loop;
    lo.matching = to.matching;
    lo.ransac = to.ransac;
    lo.fit = projection_fit_options(to);
    closer = LoopCloser::create(
        lo, cam, s->map_, std::make_shared<const BinaryVocabulary>(std::move(*vocabulary)), error);
    if (!closer) return nullptr;
  }

  LocalMapSystem* self = s.get();
  s->checkpointer_ = std::make_unique<MapCheckpointer>(
      opts.checkpoint_path, opts.checkpoint_period_s, s->map_, s->map_file_context());
  if (!opts.checkpoint_path.empty())
    s->checkpoint_ = std::make_unique<CheckpointStage>(s->checkpointer_.get(), pacing);
  if (closer)
    s->loop_closing_ = std::make_unique<LoopClosingStage>(std::move(*closer), pacing,
                                                          [self] { self->map_changed(); });
  s->mapping_ =
      std::make_unique<LocalMappingStage>(std::move(*mapper), pacing, [self](std::int64_t kf) {
        // With loop closing, the checkpoint follows it (the map as loop-corrected).
        if (self->loop_closing_)
          self->loop_closing_->submit(kf);
        else
          self->map_changed();
      });
  s->tracking_ = std::make_unique<TrackingStage>(
      std::move(*extractor), std::move(*tracker), pacing,
      [self] {
        std::size_t load = self->mapping_->load();
        if (self->map_->schedule)
          load = static_cast<std::size_t>(
              self->map_->schedule->answer(MapParty::kTracking, static_cast<std::int64_t>(load)));
        return keyframe_admission(load, self->options_.keyframe_gate_mapper_busy);
      },
      records, [self](std::int64_t kf) { self->keyframe_made(kf); }, k,
      opts.tracker.align_depth_time, opts.tracker.colour_stamp_lag_s);
  if (s->checkpoint_) s->checkpoint_->start();
  s->tracking_->start();
  s->mapping_->start();
  if (s->loop_closing_) s->loop_closing_->start();
  return s;
}

LocalMapSystem::~LocalMapSystem() { finish(); }

void LocalMapSystem::keyframe_made(std::int64_t kf) {
  mapping_->submit(kf);
  if (options_.mode != PipelineMode::kWait) return;
  // Deterministic: the next frame is tracked against the map as mapped and loop-closed. Mapping
  // hands the keyframe to loop closing before it reports idle, so this order sees both.
  mapping_->wait_idle();
  if (loop_closing_) loop_closing_->wait_idle();
}

void LocalMapSystem::map_changed() {
  if (!checkpoint_) return;
  if (const std::optional<double> now_s = checkpointer_->map_changed())
    checkpoint_->request(*now_s);
}

void LocalMapSystem::submit(RgbdFrame frame) {
  // A checkpoint pending since a keyframe with none after it (a hover) falls due at a frame: a
  // lock-free check per frame; the map is copied and written on the checkpoint thread.
  if (checkpoint_ && checkpointer_->take_due(frame.stamp_s)) checkpoint_->request(frame.stamp_s);
  tracking_->submit(std::move(frame));
}

void LocalMapSystem::finish() {
  if (finished_.exchange(true)) return;
  // In the order frames flow, so that each stage drains what the one before handed it.
  LockSchedule* schedule = map_->schedule.get();
  if (tracking_) tracking_->finish();
  if (schedule) schedule->retire(MapParty::kTracking);
  if (mapping_) mapping_->finish();
  if (schedule) schedule->retire(MapParty::kMapping);
  if (loop_closing_) loop_closing_->finish();
  if (schedule) {
    schedule->retire(MapParty::kLoopClosing);
    schedule->flush();
  }
  if (checkpoint_) checkpoint_->finish();
  if (checkpointer_) checkpointer_->write_forced();
}

PipelineSummary LocalMapSystem::summary() const {
  PipelineSummary s;
  tracking_->add_to(&s);
  mapping_->add_to(&s);
  s.loop_closing_active = loop_closing_ != nullptr;
  const CheckpointStats cp = checkpointer_->stats();
  s.checkpoints_written = cp.written;
  s.checkpoint_max_ms = cp.max_ms;
  s.checkpoint_error = cp.error;
  if (map_->schedule) s.lock_schedule = map_->schedule->describe();
  {
    std::lock_guard<MapMutex> lock(map_->mutex);
    s.keyframes = map_->map.keyframes().size();
    s.map_points = map_->map.points().size();
    s.keyframes_culled = map_->map.culled().size();
    s.loop_closures = map_->map.loop_edges().size();
  }
  if (loop_closing_)
    for (const LoopStats& l : loop_closing_->stats()) s.loop_detections += l.candidates > 0 ? 1 : 0;
  return s;
}

std::vector<LoopStats> LocalMapSystem::loop_stats() const {
  return loop_closing_ ? loop_closing_->stats() : std::vector<LoopStats>{};
}

std::vector<std::pair<double, Eigen::Isometry3d>> LocalMapSystem::final_trajectory() const {
  std::vector<std::pair<double, Eigen::Isometry3d>> out;
  records_->read([&](const std::deque<FrameRecord>& records) {
    // Each tracked frame re-anchored to the final pose of its reference keyframe.
    std::lock_guard<MapMutex> map_lock(map_->mutex);
    for (const auto& r : records) {
      if (!r.ok) continue;
      const auto T_kf =
          r.reference_keyframe >= 0 ? map_->map.resolve_pose(r.reference_keyframe) : std::nullopt;
      out.emplace_back(r.stamp_s, T_kf && r.state == TrackingState::kTracking ? *T_kf * r.T_kf_cam
                                                                              : r.T_world_cam);
    }
  });
  return out;
}

MapFileContext LocalMapSystem::map_file_context() const {
  return MapFileContext{camera_, options_.frontend.features};
}

bool LocalMapSystem::open_lock_schedule(std::string* error) {
  const std::string& record = options_.lock_schedule_record_path;
  const std::string& replay = options_.lock_schedule_replay_path;
  if (!record.empty() && !replay.empty()) {
    if (error) *error = "a lock schedule is either recorded or replayed, not both";
    return false;
  }
  if (!record.empty()) map_->schedule = LockSchedule::recorder(record, error);
  if (!replay.empty()) map_->schedule = LockSchedule::replayer(replay, error);
  return (record.empty() && replay.empty()) || map_->schedule != nullptr;
}

bool LocalMapSystem::load_map(const std::string& path, std::string* error) {
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
  tracking_->tracker().set_lost();  // the first frames relocalise in the loaded map
  if (loop_closing_) loop_closing_->closer().index_map();
  return true;
}

bool LocalMapSystem::save_map(const std::string& path, std::string* error) const {
  std::lock_guard<MapMutex> lock(map_->mutex);
  return slam::save_map(path, map_->map, map_file_context(), error, map_->corrections);
}

}  // namespace rgbdquad::slam
