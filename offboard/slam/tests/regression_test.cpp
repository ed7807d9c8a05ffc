// End-to-end regression on the real excerpt shipped in tests/data (fr1_xyz, first 30 frames):
// the whole pipeline, scored with slam_metrics against the motion-capture ground truth.
// Bounds come from measured runs (see the comments); they leave room for libm/OpenCV differences
// but fail on any real regression (VO drift on these frames is several times larger).
#include <gtest/gtest.h>

#include "slam/dataset/tum_dataset.hpp"
#include "slam/eval/metrics.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace slam {
namespace {

const std::string kExcerpt = std::string(SLAM_REPO_DIR) + "/tests/data/fr1_xyz_first30";

struct RunResult {
  eval::Trajectory trajectory;
  PipelineSummary summary;
  double ate_m = -1, rpe_mm = -1, rpe_deg = -1;
};

RunResult run(DetectorKind kind, BackendKind backend, PipelineMode mode) {
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
    if (f) p->submit(std::move(*f));
  }
  p->finish();
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
  // Measured 2026-11-22 (slam-eval defaults, this machine): ATE 6.5 mm, RPE 8.40 mm / 0.387 deg.
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
  // Measured 2026-11-22: ATE 7.0 mm, RPE 7.88 mm / 0.396 deg.
  EXPECT_LT(a.ate_m, 0.010);
  EXPECT_LT(a.rpe_mm, 11.0);
}

}  // namespace
}  // namespace slam
