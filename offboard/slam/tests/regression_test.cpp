// End-to-end regression on the real excerpt shipped in tests/data (fr1_xyz, first 30 frames):
// the whole pipeline, scored with slam_metrics against the motion-capture ground truth.
// Bounds come from measured runs (see the comments); they leave room for libm/OpenCV differences
// but fail on any real regression (VO drift on these frames is several times larger).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "rgbdquad/eval/metrics.hpp"
#include "slam/dataset/tum_dataset.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace rgbdquad::slam {
namespace {

const std::string kExcerpt = std::string(SLAM_REPO_DIR) + "/tests/data/fr1_xyz_first30";

struct RunResult {
  eval::Trajectory trajectory;
  PipelineSummary summary;
  double ate_m = -1, rpe_mm = -1, rpe_deg = -1;
};

/// Optional per-frame edit: return false to withhold the frame, or change its images.
using FrameEdit = std::function<bool(RgbdFrame*)>;

RunResult run(DetectorKind kind, BackendKind backend, PipelineMode mode, const FrameEdit& edit = {},
              std::vector<FrameRecord>* records = nullptr) {
  RunResult r;
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  EXPECT_TRUE(ds) << err;
  if (!ds) return r;
  PipelineOptions o;
  o.frontend.features.kind = kind;
  o.backend.kind = backend;
  o.mode = mode;
  auto p = Pipeline::create(o, Intrinsics{}, &err);
  EXPECT_TRUE(p) << err;
  if (!p) return r;
  for (std::size_t i = 0; i < ds->size(); ++i) {
    auto f = ds->load(i, &err);
    EXPECT_TRUE(f) << err;
    if (f && (!edit || edit(&*f))) p->submit(std::move(*f));
  }
  p->finish();
  if (records) *records = p->records();
  for (const auto& [t, T] : p->final_trajectory()) r.trajectory.push_back({t, T});
  r.summary = p->summary();
  auto gt = eval::read_tum_trajectory(ds->groundtruth_path(), &err);
  EXPECT_TRUE(gt) << err;
  if (!gt) return r;
  auto ate = eval::compute_ate(*gt, r.trajectory, eval::kDefaultMaxDtS, &err);
  auto rpe = eval::compute_rpe(*gt, r.trajectory, eval::kDefaultMaxDtS, &err);
  EXPECT_TRUE(ate && rpe) << err;
  if (ate) r.ate_m = ate->trans_rmse_m;
  if (rpe) {
    r.rpe_mm = rpe->trans_rmse_mm;
    r.rpe_deg = rpe->rot_rmse_deg;
  }
  return r;
}

TEST(Regression, SiftGlcWaitModeOnFr1XyzFirst30) {
  const RunResult r = run(DetectorKind::kSift, BackendKind::kGlc, PipelineMode::kWait);
  ASSERT_EQ(r.trajectory.size(), 30u);
  EXPECT_EQ(r.summary.frames_failed, 0u);
  EXPECT_GE(r.summary.keyframes, 1u);
  // Measured with slam-eval's defaults: ATE 6.5 mm, RPE 8.40 mm / 0.387 deg.
  EXPECT_LT(r.ate_m, 0.010);
  EXPECT_LT(r.rpe_mm, 11.0);
  EXPECT_LT(r.rpe_deg, 0.5);
}

TEST(Regression, OrbWaitModeEqualsSequentialMode) {
  // Wait mode runs two threads but must give exactly the sequential result (deterministic).
  const RunResult a = run(DetectorKind::kOrb, BackendKind::kGlc, PipelineMode::kWait);
  const RunResult b = run(DetectorKind::kOrb, BackendKind::kGlc, PipelineMode::kSequential);
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  for (std::size_t i = 0; i < a.trajectory.size(); ++i)
    EXPECT_TRUE(a.trajectory[i].T_world_cam.isApprox(b.trajectory[i].T_world_cam, 1e-12)) << i;
  // Measured: ATE 7.0 mm, RPE 7.88 mm / 0.396 deg.
  EXPECT_LT(a.ate_m, 0.010);
  EXPECT_LT(a.rpe_mm, 11.0);
}

TEST(Regression, LocalMapWaitModeEqualsSequentialModeAndIsAccurate) {
  // The system that flies: wait mode (tracking and mapping threads) must equal sequential.
  const RunResult a = run(DetectorKind::kOrb, BackendKind::kLocalMap, PipelineMode::kWait);
  const RunResult b = run(DetectorKind::kOrb, BackendKind::kLocalMap, PipelineMode::kSequential);
  ASSERT_EQ(a.trajectory.size(), 30u);
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  for (std::size_t i = 0; i < a.trajectory.size(); ++i)
    EXPECT_TRUE(a.trajectory[i].T_world_cam.isApprox(b.trajectory[i].T_world_cam, 1e-12)) << i;
  EXPECT_EQ(a.summary.frames_lost, 0u);
  EXPECT_GE(a.summary.keyframes, 2u);
  // Measured: ATE 6.2 mm, RPE 6.67 mm (the thesis ORB VO+GLC: 7.0 / 7.88).
  EXPECT_LT(a.ate_m, 0.010);
  EXPECT_LT(a.rpe_mm, 11.0);
}

/// The system that flies (ORB, local map) in `mode`.
PipelineOptions orb_local_map(PipelineMode mode) {
  PipelineOptions o;
  o.frontend.features.kind = DetectorKind::kOrb;
  o.backend.kind = BackendKind::kLocalMap;
  o.mode = mode;
  return o;
}

/// An ORB local-map pipeline in sequential mode (null, with a test failure, when refused).
std::unique_ptr<Pipeline> sequential_orb_local_map() {
  std::string err;
  auto p = Pipeline::create(orb_local_map(PipelineMode::kSequential), Intrinsics{}, &err);
  EXPECT_TRUE(p) << err;
  return p;
}

/// The records of an ORB local-map run of the excerpt with `options`.
std::vector<FrameRecord> local_map_records(const PipelineOptions& options) {
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  EXPECT_TRUE(ds) << err;
  auto p = Pipeline::create(options, Intrinsics{}, &err);
  EXPECT_TRUE(p) << err;
  if (!ds || !p) return {};
  for (std::size_t i = 0; i < ds->size(); ++i)
    if (auto f = ds->load(i, &err)) p->submit(std::move(*f));
  p->finish();
  return p->records();
}

TEST(Regression, LocalMapWithARollingShutterEstimatesTheRateOfEveryTrackedFrame) {
  // GIVEN the Kinect v1's 24 ms readout (protocol/camera/tum_cameras.json), and a global shutter
  PipelineOptions rolling = orb_local_map(PipelineMode::kWait);
  rolling.tracker.rolling_shutter_readout_s = camera::kTumFr1.rolling_shutter_readout_s;
  ASSERT_GT(rolling.tracker.rolling_shutter_readout_s, 0.0);
  PipelineOptions sequential = rolling;
  sequential.mode = PipelineMode::kSequential;
  // WHEN the excerpt is tracked
  const std::vector<FrameRecord> a = local_map_records(rolling);
  const std::vector<FrameRecord> b = local_map_records(sequential);
  const std::vector<FrameRecord> global = local_map_records(orb_local_map(PipelineMode::kWait));
  // THEN every frame tracked after the first has a rate a hand-held camera can turn at, the run
  // is as deterministic as without it, and a global shutter reports none
  ASSERT_EQ(a.size(), 30u);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 1; i < a.size(); ++i) {
    EXPECT_EQ(a[i].state, TrackingState::kTracking) << i;
    ASSERT_TRUE(a[i].rolling_shutter_rate_rad_per_s) << i;
    const auto& w = *a[i].rolling_shutter_rate_rad_per_s;
    EXPECT_LT(std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), 3.0) << i;
    ASSERT_TRUE(b[i].rolling_shutter_rate_rad_per_s) << i;
    EXPECT_EQ(*b[i].rolling_shutter_rate_rad_per_s, w) << i;
  }
  for (const FrameRecord& r : global) EXPECT_FALSE(r.rolling_shutter_rate_rad_per_s);
}

TEST(Pipeline, RetiredRecordsGoToTheSinkInOrderAndOnlyTheNewestAreHeld) {
  // GIVEN a local-map pipeline that keeps its 5 newest records (slam-server keeps a second's)
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  auto p = sequential_orb_local_map();
  ASSERT_TRUE(p);
  std::vector<std::int64_t> retired;
  std::size_t retired_tracked = 0;
  p->retire_records(5, [&](const FrameRecord& r) {
    retired.push_back(r.index);
    retired_tracked += r.state == TrackingState::kTracking ? 1 : 0;
  });
  // WHEN the 30 frames go through it
  for (std::size_t i = 0; i < ds->size(); ++i) {
    auto f = ds->load(i, &err);
    ASSERT_TRUE(f) << err;
    const std::int64_t index = f->index;
    p->submit(std::move(*f));
    // THEN the newest record is always there to answer the frame
    ASSERT_TRUE(p->record(index)) << index;
  }
  p->finish();
  // AND the 25 older ones went to the sink once each, in order, complete (all tracked)
  ASSERT_EQ(retired.size(), ds->size() - 5);
  for (std::size_t k = 0; k < retired.size(); ++k)
    EXPECT_EQ(retired[k], static_cast<std::int64_t>(k));
  EXPECT_EQ(retired_tracked, retired.size());
  // AND only the 5 newest are held
  const std::vector<FrameRecord> held = p->records();
  ASSERT_EQ(held.size(), 5u);
  EXPECT_EQ(held.front().index, static_cast<std::int64_t>(ds->size() - 5));
  EXPECT_FALSE(p->record(0));
  EXPECT_EQ(p->summary().frames_failed, 0u);
}

TEST(Pipeline, KeyframeAdmissionLetsWeakTrackingPastABusyMapperUpToTheHardCap) {
  // GIVEN the gate on a busy mapper off (the default)
  // WHEN the mapper holds fewer than kMaxQueuedKeyframes THEN keyframes are made as needed
  for (std::size_t n = 0; n < kMaxQueuedKeyframes; ++n) {
    EXPECT_TRUE(keyframe_admission(n, false).allowed) << n;
    EXPECT_TRUE(keyframe_admission(n, false).mapper_idle) << n;
  }
  // WHEN it holds kMaxQueuedKeyframes THEN only weak tracking makes one (mapper_idle false)
  for (std::size_t n = kMaxQueuedKeyframes; n < kMaxQueuedKeyframesWeak; ++n) {
    EXPECT_TRUE(keyframe_admission(n, false).allowed) << n;
    EXPECT_FALSE(keyframe_admission(n, false).mapper_idle) << n;
  }
  // WHEN it holds kMaxQueuedKeyframesWeak THEN none
  EXPECT_FALSE(keyframe_admission(kMaxQueuedKeyframesWeak, false).allowed);
  // AND a frame that would be lost still starts a map segment, up to a hard cap of its own
  for (std::size_t n = 0; n < kMaxQueuedKeyframesSegmentStart; ++n)
    EXPECT_TRUE(keyframe_admission(n, false).segment_start_allowed) << n;
  EXPECT_FALSE(keyframe_admission(kMaxQueuedKeyframesSegmentStart, false).segment_start_allowed);
  // AND with the gate on, any keyframe in the mapper leaves keyframes to weak tracking
  EXPECT_TRUE(keyframe_admission(0, true).mapper_idle);
  EXPECT_FALSE(keyframe_admission(1, true).mapper_idle);
  EXPECT_TRUE(keyframe_admission(1, true).allowed);
}

/// The mapping thread's scheduling in a kLive pipeline created by a thread raised to SCHED_RR
/// (slam-server's serving thread), with `mapping_rt_priority`; `creator_realtime` says whether the
/// OS granted the creator's raise.
std::string live_mapping_thread(int mapping_rt_priority, bool* creator_realtime) {
  std::string described;
  std::thread creator([&] {
    *creator_realtime = raise_current_thread(ThreadPriorityOptions{}).realtime;
    PipelineOptions o = orb_local_map(PipelineMode::kLive);
    o.mapping_rt_priority = mapping_rt_priority;
    std::string err;
    auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
    auto p = Pipeline::create(o, Intrinsics{}, &err);
    ASSERT_TRUE(ds && p) << err;
    for (std::size_t i = 0; i < 5; ++i) {
      auto f = ds->load(i, &err);
      ASSERT_TRUE(f) << err;
      p->submit(std::move(*f));
    }
    p->finish();
    described = p->summary().mapping_thread;
  });
  creator.join();
  return described;
}

TEST(Pipeline, UnderARealTimeTrackerMappingRunsRealTimeBelowIt) {
  // GIVEN a live pipeline created by a real-time (SCHED_RR 10) thread
  bool realtime = false;
  const std::string rr = live_mapping_thread(5, &realtime);
  if (realtime) {
    // THEN its mapper runs SCHED_RR 5: below tracking, above every process's normal work
    EXPECT_EQ(rr, "mapping thread: SCHED_RR priority 5");
  } else {
    // (without CAP_SYS_NICE: the normal policy, and the reason is given)
    EXPECT_NE(rr.find("mapping thread: "), std::string::npos) << rr;
    EXPECT_EQ(rr.find("SCHED_RR"), std::string::npos) << rr;
  }
  // AND with mapping_rt_priority 0 it drops to the normal policy, below the tracker by policy
  const std::string normal = live_mapping_thread(0, &realtime);
  EXPECT_EQ(normal.find("SCHED_RR"), std::string::npos) << normal;
  if (realtime) {
    EXPECT_EQ(normal, "mapping thread: nice -10 (below a real-time creator)");
  }
}

/// Names of this process's threads (/proc/self/task/*/comm).
std::vector<std::string> thread_names() {
  std::vector<std::string> names;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(task.path() / "comm");
    std::string name;
    if (std::getline(comm, name)) names.push_back(name);
  }
  return names;
}

TEST(Pipeline, ItsThreadsAreNamedSoTheirCpuCanBeAttributed) {
  // GIVEN a wait-mode local-map pipeline with loop closing (tracking, mapping and loop threads)
  PipelineOptions o = orb_local_map(PipelineMode::kWait);
  o.loop_closing = true;
  std::string err;
  auto p = Pipeline::create(o, Intrinsics{}, &err);
  ASSERT_TRUE(p) << err;
  // WHEN its threads have started (each names itself first thing)
  std::vector<std::string> names;
  for (int i = 0; i < 200; ++i) {
    names = thread_names();
    const auto has = [&](const char* n) {
      return std::find(names.begin(), names.end(), n) != names.end();
    };
    if (has("slam-tracking") && has("slam-mapping") && has("slam-loop")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  p->finish();
  // THEN top -H / ps -L / the HIL's per-thread CPU report see them by name
  for (const char* n : {"slam-tracking", "slam-mapping", "slam-loop"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
}

TEST(Regression, LocalMapBridgesAGapOfWithheldFrames) {
  // GIVEN frames 10-19 withheld (a third of a second: a stalled link)
  std::vector<FrameRecord> recs;
  const RunResult r = run(
      DetectorKind::kOrb, BackendKind::kLocalMap, PipelineMode::kSequential,
      [](RgbdFrame* f) { return f->index < 10 || f->index >= 20; }, &recs);
  // THEN every frame after the gap is tracked in the same map (no new world frame) and accurate
  ASSERT_EQ(r.trajectory.size(), 20u);
  for (const auto& rec : recs) EXPECT_EQ(rec.state, TrackingState::kTracking) << rec.index;
  EXPECT_LT(r.ate_m, 0.015);
  // AND the first frame after the gap, whose prediction no longer vouches for it, was also checked
  // against the keyframe database (a projection fit from a stale pose can lock onto repeated
  // texture at the wrong offset), and only that frame
  for (const auto& rec : recs) {
    EXPECT_EQ(rec.prediction_stale, rec.index == 20) << rec.index;
    if (rec.index == 20) {
      EXPECT_GT(rec.ransac_ms, 0.0);
    }
  }
}

TEST(Regression, LocalMapSurvivesBlankAndDepthlessFramesWithoutAPoseJump) {
  // GIVEN frame 12 black, frame 13 without depth, frame 14 with NaN-free but all-zero depth + image
  std::vector<FrameRecord> recs;
  const RunResult r = run(
      DetectorKind::kOrb, BackendKind::kLocalMap, PipelineMode::kSequential,
      [](RgbdFrame* f) {
        if (f->index == 12) f->rgb.setTo(cv::Scalar::all(0));
        if (f->index == 13 || f->index == 14) f->depth.setTo(0);
        if (f->index == 14) f->rgb.setTo(cv::Scalar::all(0));
        return true;
      },
      &recs);
  // THEN the bad frames are lost (held at the last pose, never a jump) and tracking resumes after
  ASSERT_EQ(recs.size(), 30u);
  for (std::int64_t i : {12, 13, 14}) {
    EXPECT_EQ(recs[static_cast<std::size_t>(i)].state, TrackingState::kLost) << i;
    EXPECT_TRUE(recs[static_cast<std::size_t>(i)].T_world_cam.isApprox(recs[11].T_world_cam, 1e-12))
        << i;
  }
  for (std::size_t i = 16; i < recs.size(); ++i)
    EXPECT_EQ(recs[i].state, TrackingState::kTracking) << i;
  EXPECT_GE(r.summary.relocalisations, 1u);
  EXPECT_LT(r.ate_m, 0.015);
}

/// Frames 0-9 of the excerpt, then frames `after` stamped from `gap_s` after frame 9 on, one frame
/// interval apart, their images changed by `change`; `attitude` (when set) travels with every frame
/// up to the one `attitude_until` (exclusive), through a sequential ORB local-map pipeline.
std::vector<FrameRecord> run_after_a_gap(const PipelineOptions& options,
                                         const std::vector<std::size_t>& after, double gap_s,
                                         const std::function<void(RgbdFrame*)>& change,
                                         std::optional<Eigen::Quaterniond> attitude = std::nullopt,
                                         std::size_t attitude_until = 1000, double stretch = 1.0) {
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  EXPECT_TRUE(ds) << err;
  auto p = ds ? Pipeline::create(options, Intrinsics{}, &err) : nullptr;
  EXPECT_TRUE(p) << err;
  if (!p) return {};
  std::vector<std::size_t> order;
  for (std::size_t i = 0; i < 10; ++i) order.push_back(i);
  order.insert(order.end(), after.begin(), after.end());
  double stamp0 = 0, stamp9 = 0;
  for (std::size_t k = 0; k < order.size(); ++k) {
    auto f = ds->load(order[k], &err);
    EXPECT_TRUE(f) << err;
    if (!f) return {};
    if (k == 0) stamp0 = f->stamp_s;
    if (k < 10) f->stamp_s = stamp0 + stretch * (f->stamp_s - stamp0);
    if (k == 9) stamp9 = f->stamp_s;
    if (k >= 10) {
      f->stamp_s = stamp9 + gap_s + 0.033 * static_cast<double>(k - 10);
      change(&*f);
    }
    f->index = static_cast<std::int64_t>(k);
    if (attitude && k < attitude_until) f->q_nav_cam = attitude;
    p->submit(std::move(*f));
  }
  p->finish();
  return p->records();
}

/// Frames 0-9 of the excerpt, then frame `jump_to`'s images stamped one frame interval after frame
/// 9 (the camera seems to have moved as far as it did in between), through a sequential ORB
/// local-map pipeline with `options`; the 11 records (empty, with a test failure, when refused).
std::vector<FrameRecord> run_with_a_jump(const PipelineOptions& options, std::size_t jump_to) {
  return run_after_a_gap(options, {jump_to}, 0.033, [](RgbdFrame*) {});
}

TEST(Regression, LocalMapNeverHandsOnAStepFasterThanTheCameraCanMove) {
  // GIVEN frames 0-9, then frame 25's images stamped one frame interval after frame 9 (a camera
  // that would have moved ~0.2 m in 33 ms, 6 m/s)
  for (const bool restart : {false, true}) {
    SCOPED_TRACE(restart ? "restart_when_lost on" : "restart_when_lost off");
    PipelineOptions o = orb_local_map(PipelineMode::kSequential);
    o.tracker.restart_when_lost = restart;
    const auto recs = run_with_a_jump(o, 25);
    ASSERT_EQ(recs.size(), 11u);
    const Eigen::Isometry3d step = recs[9].T_world_cam.inverse() * recs[10].T_world_cam;
    if (restart) {
      // THEN the frame starts a new map segment at the predicted pose: one frame interval of the
      // camera's recent motion (a few mm), not the 0.2 m jump
      EXPECT_EQ(recs[10].state, TrackingState::kTracking);
      EXPECT_TRUE(recs[10].new_segment);
      EXPECT_LT(step.translation().norm(), 0.02);
    } else {
      // THEN that frame is lost, holding frame 9's pose, instead of jumping
      EXPECT_EQ(recs[10].state, TrackingState::kLost);
      EXPECT_TRUE(recs[10].T_world_cam.isApprox(recs[9].T_world_cam, 1e-12));
    }
  }
}

TEST(Regression, LocalMapKeepsAStrongFitOffTheRecentPathWhenTheReferenceKeyframeConfirmsIt) {
  // GIVEN frames 0-9, then frame 17's images stamped one frame interval after frame 9: a step of
  // about 0.1 m, within the speed bound (2 m/s) but beyond the acceleration bound's 6 cm around
  // the recent path - a strong fit the acceleration bound alone refuses
  for (const bool confirm : {false, true}) {
    SCOPED_TRACE(confirm ? "confirm_off_path on" : "confirm_off_path off");
    PipelineOptions o = orb_local_map(PipelineMode::kSequential);
    o.tracker.confirm_off_path = confirm;
    const auto recs = run_with_a_jump(o, 17);
    ASSERT_EQ(recs.size(), 11u);
    const double step_m =
        (recs[9].T_world_cam.inverse() * recs[10].T_world_cam).translation().norm();
    EXPECT_EQ(recs[10].state, TrackingState::kTracking);
    if (confirm) {
      // THEN the registration to the reference keyframe confirms the fit, which is kept: the
      // frame is placed where its images were taken, in the same map segment
      EXPECT_TRUE(recs[10].off_path_confirmed);
      EXPECT_FALSE(recs[10].new_segment);
      EXPECT_GT(step_m, 0.05);
    } else {
      // THEN the bound is final: a new segment starts at the predicted pose, a few mm on
      EXPECT_TRUE(recs[10].new_segment);
      EXPECT_LT(step_m, 0.02);
    }
  }
}

TEST(Regression, LocalMapSegmentJoinsTheMapWhenItsPlaceIsRecognised) {
  // GIVEN frames 0-9, then frames 23-29 stamped as if they followed at once (the camera would have
  // moved ~0.2 m in one frame interval: a new map segment starts at the predicted pose, ~0.2 m
  // from the truth), then frames 9 down to 0 again (back over the first map's ground)
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  PipelineOptions o = orb_local_map(PipelineMode::kSequential);
  o.tracker.restart_when_lost = true;
  auto p = Pipeline::create(o, Intrinsics{}, &err);
  ASSERT_TRUE(p) << err;
  std::vector<std::size_t> order;
  for (std::size_t i = 0; i < 10; ++i) order.push_back(i);
  for (std::size_t i = 23; i < 30; ++i) order.push_back(i);
  for (int i = 9; i >= 0; --i) order.push_back(static_cast<std::size_t>(i));
  double stamp = 0;
  for (std::size_t k = 0; k < order.size(); ++k) {
    auto f = ds->load(order[k], &err);
    ASSERT_TRUE(f) << err;
    if (k == 0) stamp = f->stamp_s;
    f->index = static_cast<std::int64_t>(k);
    f->stamp_s = stamp + 0.033 * static_cast<double>(k);
    p->submit(std::move(*f));
  }
  p->finish();
  const auto recs = p->records();
  const PipelineSummary summary = p->summary();
  ASSERT_EQ(recs.size(), order.size());
  // THEN the segment started, was moved onto the first map when frames 9..0 were recognised, and
  // frame 0 seen again is placed where it was the first time (not ~0.2 m off with the segment)
  EXPECT_GE(summary.segments_started, 1u);
  EXPECT_EQ(summary.segments_merged, 1u);
  const Eigen::Isometry3d d = recs.front().T_world_cam.inverse() * recs.back().T_world_cam;
  EXPECT_LT(d.translation().norm(), 0.02);
  for (const auto& rec : recs) EXPECT_EQ(rec.state, TrackingState::kTracking) << rec.index;
}

TEST(Regression, LocalMapStartsASegmentAfterAStaleGapWhenNothingCanPlaceTheFrame) {
  // GIVEN frames 0-9, then after a 0.5 s gap (past the 0.2 s the prediction vouches for) frames
  // 10-19 mirrored left-right: a view no keyframe holds, which relocalisation cannot place
  const auto mirror = [](RgbdFrame* f) {
    cv::flip(f->rgb, f->rgb, 1);
    cv::flip(f->depth, f->depth, 1);
  };
  std::vector<std::size_t> after;
  for (std::size_t i = 10; i < 20; ++i) after.push_back(i);
  for (const bool restart : {false, true}) {
    SCOPED_TRACE(restart ? "restart_after_gap on" : "restart_after_gap off");
    PipelineOptions o = orb_local_map(PipelineMode::kSequential);
    o.tracker.restart_after_gap = restart;
    const auto recs = run_after_a_gap(o, after, 0.5, mirror);
    ASSERT_EQ(recs.size(), 20u);
    if (restart) {
      // THEN the first frame after the gap starts a segment at a guessed pose - frame 9's moved
      // on by at most 5 frame intervals of its motion - declared as a map correction, and every
      // frame after it is tracked in the segment
      EXPECT_TRUE(recs[10].new_segment);
      EXPECT_GT(recs[10].map_corrections, recs[9].map_corrections);
      const double last_step_m =
          (recs[8].T_world_cam.inverse() * recs[9].T_world_cam).translation().norm();
      const Eigen::Isometry3d step = recs[9].T_world_cam.inverse() * recs[10].T_world_cam;
      EXPECT_LT(step.translation().norm(), 5.5 * last_step_m + 0.001);
      for (std::size_t i = 10; i < recs.size(); ++i)
        EXPECT_EQ(recs[i].state, TrackingState::kTracking) << i;
    } else {
      // THEN without it every frame after the gap stays lost at frame 9's pose
      for (std::size_t i = 10; i < recs.size(); ++i) {
        EXPECT_EQ(recs[i].state, TrackingState::kLost) << i;
        EXPECT_TRUE(recs[i].T_world_cam.isApprox(recs[9].T_world_cam, 1e-12)) << i;
      }
    }
  }
}

TEST(Regression, LocalMapGuessAfterAStaleGapExtrapolatesNoFurtherThanTheGap) {
  // GIVEN frames 0-9 stamped 0.3 s apart (a 3.3 fps stream: every frame interval is longer than
  // the 0.2 s the prediction vouches for), then a mirrored frame one interval later that nothing
  // can place
  const auto mirror = [](RgbdFrame* f) {
    cv::flip(f->rgb, f->rgb, 1);
    cv::flip(f->depth, f->depth, 1);
  };
  const double interval_s = 0.3, stretch = interval_s / 0.033;
  const auto recs = run_after_a_gap(orb_local_map(PipelineMode::kSequential), {10}, interval_s,
                                    mirror, std::nullopt, 1000, stretch);
  ASSERT_EQ(recs.size(), 11u);
  // THEN it starts a segment one interval of the recent motion on, not five
  EXPECT_TRUE(recs[10].new_segment);
  const double last_step_m =
      (recs[8].T_world_cam.inverse() * recs[9].T_world_cam).translation().norm();
  const double step_m = (recs[9].T_world_cam.inverse() * recs[10].T_world_cam).translation().norm();
  EXPECT_GT(last_step_m, 0.005);
  EXPECT_LT(step_m, 1.5 * last_step_m + 0.001);
}

TEST(Regression, LocalMapRefusesARelocalisationThatTurnsAgainstTheAttitude) {
  // GIVEN frames 0-9 with a level attitude, then after a 2 s gap (long enough for the rate bound
  // to allow a half turn) frame 9's images turned 180 deg about the principal point:
  // relocalisation places them at a camera rolled 180 deg
  const Intrinsics k;
  const auto turn = [&](RgbdFrame* f) {
    const cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(k.cx_px, k.cy_px), 180.0, 1.0);
    cv::warpAffine(f->rgb, f->rgb, m, f->rgb.size(), cv::INTER_LINEAR);
    cv::warpAffine(f->depth, f->depth, m, f->depth.size(), cv::INTER_NEAREST);
  };
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  for (const bool with_attitude : {false, true}) {
    SCOPED_TRACE(with_attitude ? "the turned frame carries the attitude" : "it carries none");
    const auto recs = run_after_a_gap(orb_local_map(PipelineMode::kSequential), {9}, 2.0, turn,
                                      level, with_attitude ? 1000 : 10);
    ASSERT_EQ(recs.size(), 11u);
    const double roll_deg =
        Eigen::AngleAxisd((recs[9].T_world_cam.inverse() * recs[10].T_world_cam).linear()).angle() *
        180.0 / M_PI;
    if (with_attitude) {
      // THEN the attitude, which did not turn, refuses it: a segment starts at frame 9's rotation
      EXPECT_TRUE(recs[10].attitude_refused);
      EXPECT_TRUE(recs[10].new_segment);
      EXPECT_LT(roll_deg, 1.0);
    } else {
      // THEN without an attitude the turned view is taken (what the gate is for)
      EXPECT_TRUE(recs[10].relocalised);
      EXPECT_GT(roll_deg, 170.0);
    }
  }
}

TEST(Regression, LocalMapWithLoopClosingWaitModeEqualsSequentialOnAForwardBackwardRevisit) {
  // GIVEN the excerpt played forward then backward (a revisit) and a loop closer that searches from
  // the second keyframe on (the 60 frames make too few keyframes for the default bars)
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  auto run_mode = [&](PipelineMode mode, std::vector<LoopStats>* loops) {
    PipelineOptions o = orb_local_map(PipelineMode::kSequential);
    o.mode = mode;
    o.loop_closing = true;
    o.loop.min_keyframes_in_map = 2;
    o.loop.keyframes_between_loops = 0;
    auto p = Pipeline::create(o, Intrinsics{}, &err);
    EXPECT_TRUE(p) << err;
    const std::size_t n = ds->size();
    for (std::size_t i = 0; i < 2 * n; ++i) {
      auto f = ds->load(i < n ? i : 2 * n - 1 - i, &err);
      f->index = static_cast<std::int64_t>(i);
      f->stamp_s = 1000.0 + static_cast<double>(i) / 30.0;
      p->submit(std::move(*f));
    }
    p->finish();
    *loops = p->loop_stats();
    EXPECT_TRUE(p->summary().loop_closing_active);
    return p->final_trajectory();
  };
  std::vector<LoopStats> la, lb;
  // WHEN it runs in wait mode (three threads) and sequentially
  const auto a = run_mode(PipelineMode::kWait, &la);
  const auto b = run_mode(PipelineMode::kSequential, &lb);
  // THEN both give the same trajectory bit for bit and the same loop-closing decisions
  ASSERT_EQ(a.size(), 60u);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_TRUE(a[i].second.isApprox(b[i].second, 1e-12)) << i;
  ASSERT_EQ(la.size(), lb.size());
  ASSERT_GE(la.size(), 2u);
  int searched = 0;
  for (std::size_t i = 0; i < la.size(); ++i) {
    EXPECT_EQ(la[i].keyframe, lb[i].keyframe);
    EXPECT_EQ(la[i].candidates, lb[i].candidates);
    EXPECT_EQ(la[i].accepted, lb[i].accepted);
    searched += la[i].searched ? 1 : 0;
  }
  EXPECT_GE(searched, 1);
}

TEST(Regression, LocalMapLiveRunReplaysBitForBitFromItsLockSchedule) {
  // GIVEN the excerpt played forward then backward (a revisit, so loop closing takes turns too)
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  const std::string schedule = (std::filesystem::temp_directory_path() /
                                ("lock-schedule-live-" + std::to_string(::getpid()) + ".txt"))
                                   .string();
  auto run_live = [&](bool record, bool paced, PipelineSummary* summary) {
    PipelineOptions o = orb_local_map(PipelineMode::kLive);
    o.loop_closing = true;
    o.loop.min_keyframes_in_map = 2;
    o.loop.keyframes_between_loops = 0;
    (record ? o.lock_schedule_record_path : o.lock_schedule_replay_path) = schedule;
    auto p = Pipeline::create(o, Intrinsics{}, &err);
    EXPECT_TRUE(p) << err;
    const std::size_t n = ds->size();
    for (std::size_t i = 0; p && i < 2 * n; ++i) {
      auto f = ds->load(i < n ? i : 2 * n - 1 - i, &err);
      f->index = static_cast<std::int64_t>(i);
      f->stamp_s = 1000.0 + static_cast<double>(i) / 30.0;
      if (paced) std::this_thread::sleep_for(std::chrono::milliseconds(33));
      p->submit(std::move(*f));
    }
    if (!p) return std::vector<FrameRecord>{};
    p->finish();
    *summary = p->summary();
    return p->records();
  };
  // WHEN a live run paced at 30 fps records its lock schedule, and the same frames are replayed
  // from it unpaced (the mapper would now lag where it kept up, and keep up where it lagged)
  PipelineSummary recorded_summary, replayed_summary;
  const auto recorded = run_live(true, true, &recorded_summary);
  const auto replayed = run_live(false, false, &replayed_summary);
  std::filesystem::remove(schedule);
  // THEN every frame's pose, keyframe decision and match count is the recorded run's, bit for bit,
  // and the replay followed the record to its end
  ASSERT_EQ(recorded.size(), 60u);
  ASSERT_EQ(replayed.size(), recorded.size());
  for (std::size_t i = 0; i < recorded.size(); ++i) {
    EXPECT_EQ(replayed[i].T_world_cam.matrix(), recorded[i].T_world_cam.matrix()) << i;
    EXPECT_EQ(replayed[i].keyframe, recorded[i].keyframe) << i;
    EXPECT_EQ(replayed[i].inliers, recorded[i].inliers) << i;
    EXPECT_EQ(replayed[i].map_points, recorded[i].map_points) << i;
  }
  EXPECT_NE(recorded_summary.lock_schedule.find("recorded"), std::string::npos);
  EXPECT_EQ(replayed_summary.lock_schedule.find("ran free"), std::string::npos)
      << replayed_summary.lock_schedule;
  EXPECT_NE(replayed_summary.lock_schedule.find("lock-step replay"), std::string::npos);
}

TEST(Regression, LocalMapSavedThenReloadedRelocalisesInTheSameWorldFrame) {
  // GIVEN a map saved after the first 20 frames
  const std::string path = ::testing::TempDir() + "/localmap_test.map";
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  const PipelineOptions o = orb_local_map(PipelineMode::kSequential);
  std::vector<FrameRecord> first;
  {
    auto p = Pipeline::create(o, Intrinsics{}, &err);
    ASSERT_TRUE(p) << err;
    for (std::size_t i = 0; i < 20; ++i) p->submit(std::move(*ds->load(i, &err)));
    p->finish();
    first = p->records();
    ASSERT_TRUE(p->save_map(path, &err)) << err;
  }
  // WHEN a new run loads it and sees frames 20-29 (indices restart at 0, as in a new process)
  auto p = Pipeline::create(o, Intrinsics{}, &err);
  ASSERT_TRUE(p) << err;
  ASSERT_TRUE(p->load_map(path, &err)) << err;
  for (std::size_t i = 20; i < 30; ++i) {
    auto f = ds->load(i, &err);
    f->index -= 20;
    p->submit(std::move(*f));
  }
  p->finish();
  const auto recs = p->records();
  // THEN it relocalises at once and continues the first run's trajectory (same world frame)
  ASSERT_EQ(recs.size(), 10u);
  EXPECT_EQ(recs[0].state, TrackingState::kTracking);
  EXPECT_GE(p->summary().relocalisations, 1u);
  const double step_m =
      (recs[0].T_world_cam.translation() - first.back().T_world_cam.translation()).norm();
  EXPECT_LT(step_m, 0.05) << "frame 20 lies " << step_m << " m from frame 19: another world frame?";
  for (const auto& r : recs) EXPECT_EQ(r.state, TrackingState::kTracking) << r.index;
}

TEST(Regression, MapFilesThatDoNotFitAreRefusedWithAReason) {
  const std::string path = ::testing::TempDir() + "/localmap_bad.map";
  std::string err;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  const PipelineOptions o = orb_local_map(PipelineMode::kSequential);
  {
    auto p = Pipeline::create(o, Intrinsics{}, &err);
    for (std::size_t i = 0; i < 3; ++i) p->submit(std::move(*ds->load(i, &err)));
    p->finish();
    ASSERT_TRUE(p->save_map(path, &err)) << err;
  }
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto write = [&](const std::string& b) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(b.data(), static_cast<std::streamsize>(b.size()));
  };
  auto refused = [&](const PipelineOptions& opts, const Intrinsics& k, const char* expect) {
    auto p = Pipeline::create(opts, k, &err);
    err.clear();
    EXPECT_FALSE(p->load_map(path, &err));
    EXPECT_NE(err.find(expect), std::string::npos) << err;
  };
  // another camera
  Intrinsics fr2;
  ASSERT_TRUE(Intrinsics::from_name("fr2", &fr2, &err));
  refused(o, fr2, "another camera");
  // another detector
  PipelineOptions sift = o;
  sift.frontend.features.kind = DetectorKind::kSift;
  refused(sift, Intrinsics{}, "another feature detector");
  // the previous version (2: no map corrections) and a future one
  std::string v = bytes;
  ASSERT_EQ(v[8], 3) << "kMapFileVersion changed: update this test";
  v[8] = 2;
  write(v);
  refused(o, Intrinsics{}, "format version 2, this build reads version 3");
  v[8] = 4;
  write(v);
  refused(o, Intrinsics{}, "format version 4");
  // one flipped byte in the middle, and a truncated file
  std::string c = bytes;
  c[c.size() / 2] = static_cast<char>(c[c.size() / 2] ^ 0x5A);
  write(c);
  refused(o, Intrinsics{}, "checksum");
  write(bytes.substr(0, bytes.size() / 3));
  refused(o, Intrinsics{}, "checksum");
  write("hello");
  refused(o, Intrinsics{}, "bad magic");
  // the thesis back-ends have no map to load
  PipelineOptions glc = o;
  glc.backend.kind = BackendKind::kGlc;
  refused(glc, Intrinsics{}, "localmap");
}

}  // namespace
}  // namespace rgbdquad::slam
