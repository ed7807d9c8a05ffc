// Run metrics; see run_metrics.hpp. Keys and statistics are what slam-eval has always written.
#include "slam/report/run_metrics.hpp"

#include <algorithm>

namespace rgbdquad::slam {

using nlohmann::json;

json stage_stats(std::vector<double> v) {
  json j;
  j["count"] = v.size();
  if (v.empty()) return j;
  std::sort(v.begin(), v.end());
  double s = 0;
  for (double x : v) s += x;
  j["mean_ms"] = s / static_cast<double>(v.size());
  j["median_ms"] = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  j["p95_ms"] =
      v[std::min(v.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(v.size())))];
  j["max_ms"] = v.back();
  return j;
}

namespace {

void add_local_map_metrics(const RunOutcome& run, json* m) {
  (*m)["keyframes_culled"] = run.summary.keyframes_culled;
  (*m)["relocalisations"] = run.summary.relocalisations;
  (*m)["frames_lost"] = run.summary.frames_lost;
  (*m)["segments_started"] = run.summary.segments_started;
  (*m)["lock_schedule"] =
      run.summary.lock_schedule.empty() ? json(nullptr) : json(run.summary.lock_schedule);
  (*m)["segments_merged"] = run.summary.segments_merged;
  (*m)["off_path_confirmed"] = run.summary.off_path_confirmed;
  (*m)["attitude_refusals"] = run.summary.attitude_refusals;
  (*m)["gravity_frames"] = run.summary.gravity_frames;
  (*m)["cross_checks"] = run.summary.cross_checks;
  (*m)["cross_check_replacements"] = run.summary.cross_check_replacements;
  std::vector<double> map_ms, map_cpu, ba_ms;
  for (const auto& st : run.mapper_stats) {
    map_ms.push_back(st.total_ms);
    map_cpu.push_back(st.total_cpu_ms);
    ba_ms.push_back(st.ba_ms);
  }
  (*m)["mapping"] = {{"keyframes_mapped", map_ms.size()},
                     {"mapping", stage_stats(map_ms)},
                     {"mapping_cpu", stage_stats(map_cpu)},
                     {"bundle_adjustment", stage_stats(ba_ms)}};
  std::vector<double> loop_ms, loop_cpu, pg_ms, snap_lock, apply_lock, fuse_lock;
  std::size_t searched = 0, ransac_ok = 0, ba_discarded = 0;
  for (const auto& l : run.loop_stats) {
    loop_ms.push_back(l.total_ms);
    loop_cpu.push_back(l.total_cpu_ms);
    snap_lock.push_back(l.snapshot_lock_ms);
    searched += l.searched ? 1 : 0;
    ransac_ok += l.verified_ransac > 0 ? 1 : 0;
    if (!l.accepted) continue;
    pg_ms.push_back(l.posegraph_ms);
    apply_lock.push_back(l.apply_lock_ms);
    fuse_lock.push_back(l.fuse_lock_ms);
  }
  for (const auto& st : run.mapper_stats) ba_discarded += st.ba_discarded ? 1 : 0;
  (*m)["loop_closing"] = {{"active", run.summary.loop_closing_active},
                          {"keyframes_processed", loop_ms.size()},
                          {"keyframes_searched", searched},
                          {"detections", run.summary.loop_detections},
                          {"ransac_verified", ransac_ok},
                          {"accepted", run.summary.loop_closures},
                          {"local_ba_discarded", ba_discarded},
                          {"loop_closing", stage_stats(loop_ms)},
                          {"loop_closing_cpu", stage_stats(loop_cpu)},
                          {"posegraph", stage_stats(pg_ms)},
                          {"snapshot_lock", stage_stats(snap_lock)},
                          {"apply_lock", stage_stats(apply_lock)},
                          {"fuse_lock_max_per_keyframe", stage_stats(fuse_lock)}};
}

/// Frames until the pose is tracked: from the start (a loaded map) and after the withheld gap.
void add_tracking_onset(const RunOutcome& run, json* m) {
  std::optional<std::size_t> first, after_gap, gap_start;
  for (std::size_t i = 0; i < run.records.size(); ++i) {
    const auto& r = run.records[i];
    if (!first && r.ok && r.state == TrackingState::kTracking) first = i;
    if (run.withhold_s > 0 && !gap_start && r.stamp_s - run.first_stamp_s >= run.withhold_from_s)
      gap_start = i;
    if (gap_start && !after_gap && r.ok && r.state == TrackingState::kTracking)
      after_gap = i - *gap_start;
  }
  (*m)["frames_until_first_tracked"] = first ? json(*first) : json(nullptr);
  if (run.withhold_s > 0)
    (*m)["frames_until_tracking_after_gap"] = after_gap ? json(*after_gap) : json(nullptr);
}

void add_stage_metrics(const RunOutcome& run, json* m) {
  std::size_t lost = 0, llc = 0;
  std::vector<double> feat, match, ransac, fe, kf, llc_ms, glc, pg, bend, nfeat, fe_cpu, be_cpu,
      lock_wait;
  for (const auto& r : run.records) {
    if (!r.ok) continue;
    if (r.state == TrackingState::kLost) ++lost;
    feat.push_back(r.features_ms);
    match.push_back(r.matching_ms);
    ransac.push_back(r.ransac_ms);
    fe.push_back(r.frontend_ms);
    fe_cpu.push_back(r.frontend_cpu_ms);
    nfeat.push_back(static_cast<double>(r.features));
    if (run.local_map) lock_wait.push_back(r.map_lock_wait_ms);
    if (!r.backend_processed) continue;
    kf.push_back(r.keyframe_ms);
    bend.push_back(r.backend_ms);
    be_cpu.push_back(r.backend_cpu_ms);
    if (r.llc_applied) {
      ++llc;
      llc_ms.push_back(r.llc_ms);
    }
    if (run.glc_backend) glc.push_back(r.glc_ms);
    if (r.loop_closed) pg.push_back(r.posegraph_ms);
  }
  (*m)["tracking_lost_frames"] = lost;
  (*m)["llc_corrections"] = llc;
  double mean_feat = 0;
  for (double x : nfeat) mean_feat += x;
  (*m)["mean_features_with_depth"] =
      nfeat.empty() ? 0.0 : mean_feat / static_cast<double>(nfeat.size());
  (*m)["stages"] = {{"features", stage_stats(feat)},
                    {"matching", stage_stats(match)},
                    {"ransac", stage_stats(ransac)},
                    {"frontend", stage_stats(fe)},
                    {"keyframe", stage_stats(kf)},
                    {"llc", stage_stats(llc_ms)},
                    {"glc", stage_stats(glc)},
                    {"posegraph", stage_stats(pg)},
                    {"backend", stage_stats(bend)},
                    {"frontend_cpu", stage_stats(fe_cpu)},
                    {"backend_cpu", stage_stats(be_cpu)},
                    {"map_lock_wait", stage_stats(lock_wait)}};
}

void add_scores(const RunOutcome& run, const std::string& groundtruth_path, json* m,
                std::string* warning) {
  std::string err;
  auto gt = eval::read_tum_trajectory(groundtruth_path, &err);
  if (!gt) {
    if (warning) *warning = "ground truth unreadable, not scored: " + err;
    (*m)["ground_truth"] = nullptr;
    return;
  }
  auto ate = eval::compute_ate(*gt, run.final_trajectory, eval::kDefaultMaxDtS, &err);
  auto rpe = eval::compute_rpe(*gt, run.final_trajectory, eval::kDefaultMaxDtS, &err);
  auto ate_online = eval::compute_ate(*gt, run.online_trajectory, eval::kDefaultMaxDtS, &err);
  if (ate) {
    (*m)["ate_rmse_m"] = ate->trans_rmse_m;
    (*m)["ate_mean_m"] = ate->trans_mean_m;
    (*m)["ate_median_m"] = ate->trans_median_m;
    (*m)["ate_max_m"] = ate->trans_max_m;
    (*m)["ate_rot_rmse_deg"] = ate->rot_rmse_deg;
    (*m)["ate_pairs"] = ate->pairs;
  }
  if (ate_online) (*m)["ate_online_rmse_m"] = ate_online->trans_rmse_m;
  if (rpe) {
    (*m)["rpe_trans_rmse_mm"] = rpe->trans_rmse_mm;
    (*m)["rpe_trans_mean_mm"] = rpe->trans_mean_mm;
    (*m)["rpe_rot_rmse_deg"] = rpe->rot_rmse_deg;
    (*m)["rpe_rot_mean_deg"] = rpe->rot_mean_deg;
    (*m)["rpe_pairs"] = rpe->pairs;
  }
  if ((!ate || !rpe) && warning) *warning = "scoring incomplete: " + err;
}

}  // namespace

RunOutcome collect_run_outcome(const Pipeline& pipeline) {
  RunOutcome run;
  run.records = pipeline.records();
  run.summary = pipeline.summary();
  run.mapper_stats = pipeline.mapper_stats();
  run.loop_stats = pipeline.loop_stats();
  run.local_map = pipeline.is_local_map();
  for (const auto& [t, T] : pipeline.final_trajectory()) run.final_trajectory.push_back({t, T});
  for (const auto& r : run.records)
    if (r.ok) run.online_trajectory.push_back({r.stamp_s, r.T_world_cam});
  return run;
}

void add_run_metrics(const RunOutcome& run, const std::string& groundtruth_path, json* m,
                     std::string* warning) {
  const PipelineSummary& s = run.summary;
  (*m)["tracking_thread"] = s.tracking_thread;
  (*m)["mapping_thread"] = s.mapping_thread;
  (*m)["mapper_caught_up"] = s.mapper_caught_up;
  (*m)["mapper_ba_interrupted"] = s.mapper_ba_interrupted;
  (*m)["frames"] = run.records.size();
  (*m)["frames_submitted"] = s.frames_submitted;
  (*m)["frames_failed"] = s.frames_failed;
  (*m)["frontend_dropped"] = s.frontend_dropped;
  (*m)["backend_skipped"] = s.backend_skipped;
  (*m)["keyframes"] = s.keyframes;
  (*m)["loop_closures"] = s.loop_closures;
  (*m)["optimisations"] = s.optimisations;
  (*m)["map_points"] = run.local_map ? static_cast<long>(s.map_points) : run.exported_map_points;
  if (run.local_map) add_local_map_metrics(run, m);
  (*m)["wall_s"] = run.wall_s;
  (*m)["frames_withheld"] = run.frames_withheld;
  add_tracking_onset(run, m);
  add_stage_metrics(run, m);
  if (!groundtruth_path.empty()) add_scores(run, groundtruth_path, m, warning);
}

}  // namespace rgbdquad::slam
