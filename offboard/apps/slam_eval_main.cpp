// slam-eval: runs the SLAM engine on a TUM RGB-D folder and scores it, or scores a trajectory.
//   slam-eval run --dataset DIR [--features sift|surf|orb] [--backend vo|llc|glc] [--rate K]
//                 [--mode wait|realtime|sequential] --out DIR
//     writes DIR/trajectory.tum (final: each frame anchored to its optimised keyframe),
//     DIR/trajectory_online.tum (poses as estimated at the time), DIR/metrics.json, DIR/map.ply,
//     DIR/graph_before.g2o, DIR/graph_after.g2o; progress on stderr.
//   slam-eval score --gt GT.txt --est EST.tum    prints the ATE/RPE JSON.
//   slam-eval vocab --dataset DIR [--dataset DIR2] --out FILE   trains the ORB bag-of-words
//     vocabulary (deterministic; offboard/slam/data/orb_vocabulary_k10_l3.bin is its output on
//     tests/data/fr1_desk_9frames, compiled into the library).
// This file is wiring only: options -> dataset -> pipeline -> writers.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "slam/dataset/tum_dataset.hpp"
#include "slam/eval/metrics.hpp"
#include "slam/pipeline/map_export.hpp"
#include "slam/pipeline/pipeline.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct RunArgs {
  std::string dataset, out, features = "orb", backend = "localmap", mode = "wait", camera = "auto";
  std::string ransac = "random", keyframe_policy = "ransac";
  int cv_threads = -1;
  int orb_features = 0, orb_levels = 0;
  double orb_scale_factor = 0;
  int rate = 1, max_frames = 0, map_stride = 8, sift_first_octave = 0, max_features = 0;
  std::uint64_t seed = 20260101;
  bool no_undistort = false, no_map = false, quiet = false, no_reprojection = false;
  std::string stamp = "auto";
  std::string save_map, load_map;
  double withhold_from_s = -1, withhold_s = 0;
  std::string keyframe_gate = slam::PipelineOptions{}.keyframe_gate_mapper_busy ? "on" : "off";
  std::string loop_closing = slam::PipelineOptions{}.loop_closing ? "on" : "off", keyframe_new_content = "on", depth_noise = "keypoint",
              map_lock = "pi", tracking_policy = "off", local_ba = "on";
  double depth_units_per_m = 0;
};

json stage_stats(std::vector<double> v) {
  json j;
  j["count"] = v.size();
  if (v.empty()) return j;
  std::sort(v.begin(), v.end());
  double s = 0;
  for (double x : v) s += x;
  j["mean_ms"] = s / static_cast<double>(v.size());
  j["median_ms"] = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  j["p95_ms"] = v[std::min(v.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(v.size())))];
  j["max_ms"] = v.back();
  return j;
}

/// Resident set size of this process, MiB (Linux /proc; -1 when unavailable). Instrumentation.
double rss_mib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return -1;
}

std::string guess_camera(const std::string& folder) {
  const std::string name = fs::path(folder).lexically_normal().filename().string() +
                           fs::absolute(folder).string();
  if (name.find("fr2") != std::string::npos || name.find("freiburg2") != std::string::npos) return "fr2";
  if (name.find("fr3") != std::string::npos || name.find("freiburg3") != std::string::npos) return "fr3";
  return "fr1";
}

int run_command(const RunArgs& a) {
  std::string err;
  if (a.cv_threads >= 0) cv::setNumThreads(a.cv_threads);
  slam::PipelineOptions po;
  if (!slam::parse_detector_kind(a.features, &po.frontend.features.kind, &err) ||
      !slam::parse_backend_kind(a.backend, &po.backend.kind, &err) ||
      !slam::parse_pipeline_mode(a.mode, &po.mode, &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 2;
  }
  po.frontend.features.undistort = !a.no_undistort;
  po.reprojection_refine = !a.no_reprojection;
  po.frontend.features.sift_upsample_first_octave = a.sift_first_octave < 0;
  po.frontend.features.sift_max_features = a.max_features;
  if (a.orb_features > 0) po.frontend.features.orb_features = a.orb_features;
  if (a.orb_levels > 0) po.frontend.features.orb_levels = a.orb_levels;
  if (a.orb_scale_factor > 0) po.frontend.features.orb_scale_factor = a.orb_scale_factor;
  po.frontend.seed = a.seed;
  po.loop_closing = a.loop_closing == "on";
  po.keyframe_gate_mapper_busy = a.keyframe_gate == "on";
  po.tracker.keyframe_needs_new_content = a.keyframe_new_content == "on";
  po.map_lock_priority_inheritance = a.map_lock == "pi";
  po.mapper.bundle_adjustment = a.local_ba == "on";
  if (!slam::parse_thread_policy(a.tracking_policy, &po.tracking_thread_policy, &err) ||
      !slam::parse_depth_noise_model(a.depth_noise, &po.depth_noise, &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 2;
  }
  po.backend.seed = a.seed + 1;
  const auto sampling = a.ransac == "thesis" ? slam::RansacSampling::kThesis : slam::RansacSampling::kRandom;
  po.frontend.ransac.sampling = sampling;
  po.backend.ransac.sampling = sampling;
  po.backend.keyframes.policy =
      a.keyframe_policy == "fixed" ? slam::KeyframePolicy::kFixedRate : slam::KeyframePolicy::kRansac;

  const std::string camera = a.camera == "auto" ? guess_camera(a.dataset) : a.camera;
  slam::Intrinsics intr;
  if (!slam::Intrinsics::from_name(camera, &intr, &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 2;
  }
  if (a.depth_units_per_m > 0) intr.depth_units_per_m = a.depth_units_per_m;
  slam::TumDatasetOptions dso;
  dso.rate_divisor = a.rate;
  dso.max_frames = a.max_frames;
  // auto: the local map's poses rest on pixel measurements in the colour image, so they carry its
  // time (ORB-SLAM2's rgbd_tum does the same); the thesis back-ends align 3D points from the depth
  // image, so they carry the depth time (RGBD-SLAM's convention, which the thesis follows).
  const std::string stamp =
      a.stamp != "auto" ? a.stamp : (po.backend.kind == slam::BackendKind::kLocalMap ? "rgb" : "depth");
  dso.stamp_from_depth = stamp == "depth";
  auto ds = slam::TumDataset::open(a.dataset, dso, &err);
  if (!ds) {
    std::cerr << "slam-eval: " << err << "\n";
    return 1;
  }
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (!fs::is_directory(a.out)) {
    std::cerr << "slam-eval: cannot create output folder '" << a.out << "'\n";
    return 1;
  }
  auto pipeline = slam::Pipeline::create(po, intr, &err);
  if (!pipeline) {
    std::cerr << "slam-eval: " << err << "\n";
    return 2;
  }
  if (!a.load_map.empty() && !pipeline->load_map(a.load_map, &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 2;
  }
  std::cerr << "slam-eval: " << ds->size() << " frames from " << a.dataset << " (camera " << camera
            << ", features " << a.features << ", backend " << a.backend << ", mode " << a.mode
            << ", rate 1/" << a.rate << ", ransac " << a.ransac << ", keyframes "
            << a.keyframe_policy << ")\n";
  const auto wall0 = std::chrono::steady_clock::now();
  const double period_s = ds->frame_period_s();
  std::size_t load_failures = 0;
  std::vector<std::pair<double, double>> rss_samples;
  double first_stamp_s = -1;
  std::size_t withheld = 0;  // (frame stamp s, RSS MiB), every 30 frames
  for (std::size_t i = 0; i < ds->size(); ++i) {
    auto frame = ds->load(i, &err);
    if (!frame) {
      std::cerr << "slam-eval: " << err << "\n";
      ++load_failures;
      if (i == 0 || load_failures > 5) {
        pipeline->finish();
        std::cerr << "slam-eval: giving up on unreadable input\n";
        return 1;
      }
      continue;
    }
    if (po.mode == slam::PipelineMode::kRealtime || po.mode == slam::PipelineMode::kLive) {
      // Real-time replay: frame i is due i * period after the start (application boundary: the
      // only place that reads the clock).
      std::this_thread::sleep_until(wall0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                std::chrono::duration<double>(period_s * static_cast<double>(i))));
    }
    const double stamp_s = frame->stamp_s;
    if (first_stamp_s < 0) first_stamp_s = stamp_s;
    if (a.withhold_s > 0 && stamp_s - first_stamp_s >= a.withhold_from_s &&
        stamp_s - first_stamp_s < a.withhold_from_s + a.withhold_s) {
      ++withheld;  // a stalled link: the frame never reaches SLAM
      continue;
    }
    pipeline->submit(std::move(*frame));
    if (i % 30 == 0) rss_samples.emplace_back(stamp_s, rss_mib());
    if (!a.quiet && ((i + 1) % 25 == 0 || i + 1 == ds->size()))
      std::cerr << "slam-eval: submitted " << (i + 1) << "/" << ds->size() << "\n";
  }
  pipeline->finish();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();

  const auto records = pipeline->records();
  const auto summary = pipeline->summary();
  slam::eval::Trajectory final_traj, online_traj;
  for (const auto& [t, T] : pipeline->final_trajectory()) final_traj.push_back({t, T});
  for (const auto& r : records) if (r.ok) online_traj.push_back({r.stamp_s, r.T_world_cam});
  const std::string traj_path = (fs::path(a.out) / "trajectory.tum").string();
  if (!slam::eval::write_tum_trajectory(traj_path, final_traj, &err) ||
      !slam::eval::write_tum_trajectory((fs::path(a.out) / "trajectory_online.tum").string(), online_traj, &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 1;
  }
  const auto& be = pipeline->backend();
  if (!slam::write_text_file((fs::path(a.out) / "graph_before.g2o").string(), be.graph_before_optimisation().to_g2o(), &err) ||
      !slam::write_text_file((fs::path(a.out) / "graph_after.g2o").string(), be.graph().to_g2o(), &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 1;
  }
  long map_points = 0;
  if (!a.no_map) {
    slam::MapExportOptions mo;
    mo.pixel_stride = a.map_stride;
    const std::string ply = (fs::path(a.out) / "map.ply").string();
    map_points = pipeline->is_local_map()
                     ? slam::write_map_points_ply(ply, *pipeline->local_map(), &err)
                     : slam::write_keyframe_map_ply(ply, be, intr, mo, &err);
    if (map_points < 0) {
      std::cerr << "slam-eval: " << err << "\n";
      return 1;
    }
  }

  if (!a.save_map.empty()) {
    if (!pipeline->save_map(a.save_map, &err)) {
      std::cerr << "slam-eval: " << err << "\n";
      return 1;
    }
    std::cerr << "slam-eval: map saved to " << a.save_map << "\n";
  }
  // Per-frame and per-keyframe tables for long-run analysis (offboard/tools/longrun.py).
  {
    std::ofstream frames_csv(fs::path(a.out) / "frames.csv");
    frames_csv << "index,stamp_s,state,keyframe,matches,inliers,frontend_ms,frontend_cpu_ms,map_keyframes,map_points,"
                  "keyframe_wanted,ref_tracked,near_tracked,near_untracked,near_redundant,map_lock_wait_ms\n";
    for (const auto& r : records)
      frames_csv << r.index << "," << std::fixed << std::setprecision(6) << r.stamp_s << ","
                 << slam::to_string(r.state) << "," << (r.keyframe ? 1 : 0) << "," << r.matches << "," << r.inliers << "," << std::setprecision(3)
                 << r.frontend_ms << "," << r.frontend_cpu_ms << "," << r.map_keyframes << "," << r.map_points << ","
                 << slam::to_string(r.keyframe_wanted) << "," << r.ref_tracked << "," << r.near_tracked << ","
                 << r.near_untracked << "," << r.near_redundant << "," << r.map_lock_wait_ms << "\n";
    std::ofstream mapping_csv(fs::path(a.out) / "mapping.csv");
    mapping_csv << "keyframe,mapping_ms,mapping_cpu_ms,ba_ms,ba_points,points_culled,points_fused,keyframes_culled\n";
    for (const auto& st : pipeline->mapper_stats())
      mapping_csv << st.keyframe << "," << std::fixed << std::setprecision(3) << st.total_ms << ","
                  << st.total_cpu_ms << "," << st.ba_ms << "," << st.ba_points << "," << st.points_culled << ","
                  << st.points_fused << "," << st.keyframes_culled << "\n";
    std::ofstream loops_csv(fs::path(a.out) / "loops.csv");
    loops_csv << "keyframe,searched,candidates,verified_ransac,accepted,loop_keyframe,ransac_inliers,fit_inliers,"
                 "correction_m,correction_deg,graph_keyframes,graph_edges,points_merged,points_attached,bow_ms,"
                 "query_ms,verify_ms,posegraph_ms,snapshot_lock_ms,apply_lock_ms,fuse_lock_ms,total_ms,total_cpu_ms,"
                 "consistent,verified_fit,refused_odometry,gate_keyframe,gate_path_m,gate_translation_m,"
                 "gate_rotation_deg,gate_chi2\n";
    for (const auto& l : pipeline->loop_stats())
      loops_csv << l.keyframe << "," << l.searched << "," << l.candidates << "," << l.verified_ransac << ","
                << l.accepted << "," << l.loop_keyframe << "," << l.ransac_inliers << "," << l.fit_inliers << ","
                << std::fixed << std::setprecision(4) << l.correction_m << "," << l.correction_deg << ","
                << l.graph_keyframes << "," << l.graph_edges << "," << l.points_merged << "," << l.points_attached
                << "," << l.bow_ms << "," << l.query_ms << "," << l.verify_ms << "," << l.posegraph_ms << ","
                << l.snapshot_lock_ms << "," << l.apply_lock_ms << "," << l.fuse_lock_ms << "," << l.total_ms << ","
                << l.total_cpu_ms << "," << l.consistent << "," << l.verified_fit << "," << l.refused_odometry
                << "," << l.gate_keyframe << "," << l.gate_path_m << "," << l.gate_translation_m << ","
                << l.gate_rotation_deg << "," << l.gate_chi2 << "\n";
    std::ofstream rss_csv(fs::path(a.out) / "rss.csv");
    rss_csv << "stamp_s,rss_mib\n";
    for (const auto& [t, mib] : rss_samples) rss_csv << std::fixed << std::setprecision(6) << t << "," << mib << "\n";
  }

  json m;
  m["dataset"] = a.dataset;
  m["camera"] = camera;
  m["features"] = a.features;
  m["backend"] = a.backend;
  m["mode"] = a.mode;
  m["rate_divisor"] = a.rate;
  m["ransac_sampling"] = a.ransac;
  m["keyframe_policy"] = a.keyframe_policy;
  m["seed"] = a.seed;
  m["sift_first_octave"] = a.sift_first_octave;
  m["max_features"] = a.max_features;
  m["undistort"] = !a.no_undistort;
  m["stamp"] = stamp;
  m["reprojection_refine"] = !a.no_reprojection;
  m["cv_threads"] = a.cv_threads;
  m["loop_closing_option"] = a.loop_closing;
  m["keyframe_new_content"] = a.keyframe_new_content;
  m["depth_noise"] = a.depth_noise;
  m["map_lock"] = a.map_lock;
  m["local_ba"] = a.local_ba;
  m["depth_units_per_m"] = intr.depth_units_per_m;
  m["tracking_policy"] = a.tracking_policy;
  m["tracking_thread"] = summary.tracking_thread;
  m["frames"] = records.size();
  m["frames_submitted"] = summary.frames_submitted;
  m["frames_failed"] = summary.frames_failed;
  m["frontend_dropped"] = summary.frontend_dropped;
  m["backend_skipped"] = summary.backend_skipped;
  m["keyframes"] = summary.keyframes;
  m["loop_closures"] = summary.loop_closures;
  m["optimisations"] = summary.optimisations;
  m["map_points"] = pipeline->is_local_map() ? static_cast<long>(summary.map_points) : map_points;
  if (pipeline->is_local_map()) {
    m["keyframes_culled"] = summary.keyframes_culled;
    m["relocalisations"] = summary.relocalisations;
    std::vector<double> map_ms, map_cpu, ba_ms;
    for (const auto& st : pipeline->mapper_stats()) {
      map_ms.push_back(st.total_ms);
      map_cpu.push_back(st.total_cpu_ms);
      ba_ms.push_back(st.ba_ms);
    }
    m["mapping"] = {{"keyframes_mapped", map_ms.size()}, {"mapping", stage_stats(map_ms)},
                    {"mapping_cpu", stage_stats(map_cpu)}, {"bundle_adjustment", stage_stats(ba_ms)}};
    std::vector<double> loop_ms, loop_cpu, pg_ms, snap_lock, apply_lock, fuse_lock;
    std::size_t searched = 0, ransac_ok = 0, ba_discarded = 0;
    for (const auto& l : pipeline->loop_stats()) {
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
    for (const auto& st : pipeline->mapper_stats()) ba_discarded += st.ba_discarded ? 1 : 0;
    m["loop_closing"] = {{"active", summary.loop_closing_active}, {"keyframes_processed", loop_ms.size()},
                         {"keyframes_searched", searched}, {"detections", summary.loop_detections},
                         {"ransac_verified", ransac_ok}, {"accepted", summary.loop_closures},
                         {"local_ba_discarded", ba_discarded},
                         {"loop_closing", stage_stats(loop_ms)}, {"loop_closing_cpu", stage_stats(loop_cpu)},
                         {"posegraph", stage_stats(pg_ms)}, {"snapshot_lock", stage_stats(snap_lock)},
                         {"apply_lock", stage_stats(apply_lock)}, {"fuse_lock_max_per_keyframe", stage_stats(fuse_lock)}};
  }
  m["wall_s"] = wall_s;
  m["frames_withheld"] = withheld;
  {
    // Frames until the pose is tracked: from the start (a loaded map) and after the withheld gap.
    std::optional<std::size_t> first, after_gap, gap_start;
    for (std::size_t i = 0; i < records.size(); ++i) {
      const auto& r = records[i];
      if (!first && r.ok && r.state == slam::TrackingState::kTracking) first = i;
      if (a.withhold_s > 0 && !gap_start && r.stamp_s - first_stamp_s >= a.withhold_from_s) gap_start = i;
      if (gap_start && !after_gap && r.ok && r.state == slam::TrackingState::kTracking) after_gap = i - *gap_start;
    }
    m["frames_until_first_tracked"] = first ? json(*first) : json(nullptr);
    if (a.withhold_s > 0) m["frames_until_tracking_after_gap"] = after_gap ? json(*after_gap) : json(nullptr);
  }
  std::size_t lost = 0, llc = 0;
  std::vector<double> feat, match, ransac, fe, kf, llc_ms, glc, pg, bend, nfeat, fe_cpu, be_cpu, lock_wait;
  for (const auto& r : records) {
    if (!r.ok) continue;
    if (r.state == slam::TrackingState::kLost) ++lost;
    feat.push_back(r.features_ms);
    match.push_back(r.matching_ms);
    ransac.push_back(r.ransac_ms);
    fe.push_back(r.frontend_ms);
    fe_cpu.push_back(r.frontend_cpu_ms);
    nfeat.push_back(static_cast<double>(r.features));
    if (pipeline->is_local_map()) lock_wait.push_back(r.map_lock_wait_ms);
    if (!r.backend_processed) continue;
    kf.push_back(r.keyframe_ms);
    bend.push_back(r.backend_ms);
    be_cpu.push_back(r.backend_cpu_ms);
    if (r.llc_applied) { ++llc; llc_ms.push_back(r.llc_ms); }
    if (po.backend.kind == slam::BackendKind::kGlc) glc.push_back(r.glc_ms);
    if (r.loop_closed) pg.push_back(r.posegraph_ms);
  }
  m["tracking_lost_frames"] = lost;
  m["llc_corrections"] = llc;
  double mean_feat = 0;
  for (double x : nfeat) mean_feat += x;
  m["mean_features_with_depth"] = nfeat.empty() ? 0.0 : mean_feat / static_cast<double>(nfeat.size());
  m["stages"] = {{"features", stage_stats(feat)},   {"matching", stage_stats(match)},
                 {"ransac", stage_stats(ransac)},   {"frontend", stage_stats(fe)},
                 {"keyframe", stage_stats(kf)},     {"llc", stage_stats(llc_ms)},
                 {"glc", stage_stats(glc)},         {"posegraph", stage_stats(pg)},
                 {"backend", stage_stats(bend)},    {"frontend_cpu", stage_stats(fe_cpu)},
                 {"backend_cpu", stage_stats(be_cpu)}, {"map_lock_wait", stage_stats(lock_wait)}};
  if (!ds->groundtruth_path().empty()) {
    auto gt = slam::eval::read_tum_trajectory(ds->groundtruth_path(), &err);
    if (!gt) {
      std::cerr << "slam-eval: ground truth unreadable, not scored: " << err << "\n";
      m["ground_truth"] = nullptr;
    } else {
      auto ate = slam::eval::compute_ate(*gt, final_traj, slam::eval::kDefaultMaxDtS, &err);
      auto rpe = slam::eval::compute_rpe(*gt, final_traj, slam::eval::kDefaultMaxDtS, &err);
      auto ate_online = slam::eval::compute_ate(*gt, online_traj, slam::eval::kDefaultMaxDtS, &err);
      if (ate) {
        m["ate_rmse_m"] = ate->trans_rmse_m;
        m["ate_mean_m"] = ate->trans_mean_m;
        m["ate_median_m"] = ate->trans_median_m;
        m["ate_max_m"] = ate->trans_max_m;
        m["ate_rot_rmse_deg"] = ate->rot_rmse_deg;
        m["ate_pairs"] = ate->pairs;
      }
      if (ate_online) m["ate_online_rmse_m"] = ate_online->trans_rmse_m;
      if (rpe) {
        m["rpe_trans_rmse_mm"] = rpe->trans_rmse_mm;
        m["rpe_trans_mean_mm"] = rpe->trans_mean_mm;
        m["rpe_rot_rmse_deg"] = rpe->rot_rmse_deg;
        m["rpe_rot_mean_deg"] = rpe->rot_mean_deg;
        m["rpe_pairs"] = rpe->pairs;
      }
      if (!ate || !rpe) std::cerr << "slam-eval: scoring incomplete: " << err << "\n";
    }
  } else {
    std::cerr << "slam-eval: no groundtruth.txt in " << a.dataset << ": trajectory not scored\n";
    m["ground_truth"] = nullptr;
  }
  std::ofstream mf(fs::path(a.out) / "metrics.json");
  mf << m.dump(2) << "\n";
  if (!mf) {
    std::cerr << "slam-eval: cannot write metrics.json\n";
    return 1;
  }
  std::cerr << "slam-eval: " << records.size() << " frames, " << summary.keyframes << " keyframes, "
            << summary.loop_closures << " loop closures, " << wall_s << " s";
  if (m.contains("ate_rmse_m"))
    std::cerr << ", ATE " << m["ate_rmse_m"].get<double>() << " m, RPE "
              << m.value("rpe_trans_rmse_mm", 0.0) << " mm / " << m.value("rpe_rot_rmse_deg", 0.0) << " deg";
  std::cerr << "\nslam-eval: wrote " << a.out << "/{trajectory.tum,trajectory_online.tum,metrics.json,"
            << (a.no_map ? "" : "map.ply,") << "graph_before.g2o,graph_after.g2o}\n";
  return 0;
}

int vocab_command(const std::vector<std::string>& datasets, const std::string& out,
                  const slam::VocabularyOptions& options) {
  std::vector<cv::Mat> images;
  std::string err;
  for (const std::string& dir : datasets) {
    const auto ds = slam::TumDataset::open(dir, slam::TumDatasetOptions{}, &err);
    slam::Intrinsics intr;
    if (!ds || !slam::Intrinsics::from_name(guess_camera(dir), &intr, &err)) {
      std::cerr << "slam-eval vocab: " << err << "\n";
      return 1;
    }
    slam::FeatureOptions fo;  // ORB with the defaults the local-map system runs
    fo.kind = slam::DetectorKind::kOrb;
    auto extractor = slam::FeatureExtractor::create(fo, intr, &err);
    if (!extractor) {
      std::cerr << "slam-eval vocab: " << err << "\n";
      return 1;
    }
    for (std::size_t i = 0; i < ds->size(); ++i) {
      auto frame = ds->load(i, &err);
      auto f = frame ? extractor->extract(*frame, &err) : std::nullopt;
      if (!f) {
        std::cerr << "slam-eval vocab: " << dir << " frame " << i << ": " << err << "\n";
        return 1;
      }
      images.push_back(f->descriptors.clone());
    }
  }
  const auto v = slam::BinaryVocabulary::train(images, options, &err);
  if (!v) {
    std::cerr << "slam-eval vocab: " << err << "\n";
    return 1;
  }
  const std::vector<std::uint8_t> bytes = v->to_bytes();
  std::ofstream f(out, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!f) {
    std::cerr << "slam-eval vocab: cannot write " << out << "\n";
    return 1;
  }
  std::size_t descriptors = 0;
  for (const cv::Mat& m : images) descriptors += static_cast<std::size_t>(m.rows);
  std::cerr << "slam-eval vocab: " << images.size() << " images, " << descriptors << " descriptors -> " << v->words()
            << " words (k " << options.branching << ", L " << options.levels << "), " << bytes.size()
            << " bytes to " << out << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"slam-eval: run the RGB-D SLAM engine on a TUM folder and score it"};
  app.require_subcommand(1);
  RunArgs a;
  auto* run = app.add_subcommand("run", "run SLAM on a TUM RGB-D folder, write trajectory + metrics");
  run->add_option("--dataset", a.dataset, "TUM folder (rgb.txt, depth.txt, optional groundtruth.txt)")->required();
  run->add_option("--out", a.out, "output folder (created)")->required();
  run->add_option("--features", a.features, "sift | surf | orb (orb keeps up at 30 fps)")->check(CLI::IsMember({"sift", "surf", "orb"}))->capture_default_str();
  run->add_option("--backend", a.backend,
                  "localmap (tracking against a local map + local mapping: the system that flies) | "
                  "vo | llc | glc (the thesis back-ends)")
      ->check(CLI::IsMember({"localmap", "vo", "llc", "glc"}))->capture_default_str();
  run->add_option("--rate", a.rate, "keep every K-th frame (frame-rate reduction 1/K)")->check(CLI::PositiveNumber)->capture_default_str();
  run->add_option("--mode", a.mode, "wait (deterministic) | realtime (paced, back-end skips) | sequential (one thread)")
      ->check(CLI::IsMember({"wait", "realtime", "live", "sequential"}))->capture_default_str();
  run->add_option("--camera", a.camera, "intrinsics: auto (from folder name) | fr1 | fr2 | fr3")
      ->check(CLI::IsMember({"auto", "fr1", "fr2", "fr3"}))->capture_default_str();
  run->add_option("--ransac", a.ransac, "random (seeded, adaptive) | thesis (4 best pairs, 10 tries)")
      ->check(CLI::IsMember({"random", "thesis"}))->capture_default_str();
  run->add_option("--keyframes", a.keyframe_policy, "ransac (thesis default) | fixed (3 per second)")
      ->check(CLI::IsMember({"ransac", "fixed"}))->capture_default_str();
  run->add_option("--max-frames", a.max_frames, "stop after N frames (0 = all)")->check(CLI::NonNegativeNumber)->capture_default_str();
  run->add_option("--seed", a.seed, "RANSAC seed")->capture_default_str();
  run->add_option("--map-stride", a.map_stride, "PLY map: every N-th pixel")->check(CLI::PositiveNumber)->capture_default_str();
  run->add_option("--sift-first-octave", a.sift_first_octave,
                  "-1: OpenCV's upsampled first octave; 0: start at input resolution (~4x faster)")
      ->check(CLI::IsMember({-1, 0}))->capture_default_str();
  run->add_option("--max-features", a.max_features, "SIFT: keep the N strongest (0 = all)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  run->add_option("--stamp", a.stamp,
                  "pose time: auto (rgb for localmap, whose poses rest on colour-image pixels; depth for "
                  "vo/llc/glc, which align depth-image points) | depth | rgb")
      ->check(CLI::IsMember({"auto", "depth", "rgb"}))->capture_default_str();
  run->add_flag("--no-reprojection-refine", a.no_reprojection,
                "skip the Gauss-Newton reprojection refinement after RANSAC");
  run->add_option("--cv-threads", a.cv_threads,
                  "OpenCV worker threads (-1 = OpenCV default; 1 makes *_cpu timings complete)")
      ->capture_default_str();
  run->add_flag("--no-undistort", a.no_undistort,
                "use keypoints as detected (default: undistort them with the camera's coefficients before lifting to 3D)");
  run->add_flag("--no-map", a.no_map, "do not write map.ply");
  run->add_option("--withhold", a.withhold_s, "seconds of frames withheld (a stalled link), see --withhold-from");
  run->add_option("--withhold-from", a.withhold_from_s, "start of the withheld span, seconds after the first frame");
  run->add_option("--save-map", a.save_map, "localmap: write the final map to this file");
  run->add_option("--load-map", a.load_map,
                  "localmap: start from this saved map (relocalise in it; poses in its world frame)");
  run->add_option("--orb-features", a.orb_features, "ORB feature count (0: default, thesis Table 4.3: 1024)");
  run->add_option("--orb-levels", a.orb_levels, "ORB pyramid levels (0: default, thesis: 6)");
  run->add_option("--orb-scale-factor", a.orb_scale_factor, "ORB pyramid scale factor (0: default, thesis: 2)");
  run->add_flag("--quiet", a.quiet, "no per-25-frame progress");
  run->add_option("--keyframe-gate", a.keyframe_gate,
                  "localmap, realtime: ORB-SLAM2's c1b/c1c rule - while the mapper is busy only weak tracking "
                  "makes a keyframe (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  run->add_option("--loop-closing", a.loop_closing,
                  "localmap: loop closing on its own thread (ORB only: the vocabulary is ORB's)")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  run->add_option("--keyframe-new-content", a.keyframe_new_content,
                  "localmap: a view change makes no keyframe that would be culled as redundant at once (>= 90 % of "
                  "its tracked near points seen by >= 3 keyframes); off: ORB-SLAM2's rule as is")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  run->add_option("--depth-noise", a.depth_noise,
                  "localmap: sigma of the depth residual - kinect (the sensor's axial noise, Nguyen et al. 2012) | "
                  "keypoint (ORB-SLAM2: the keypoint's pixel sigma on the virtual-stereo disparity)")
      ->check(CLI::IsMember({"kinect", "keypoint"}))->capture_default_str();
  run->add_option("--depth-units-per-m", a.depth_units_per_m,
                  "raw depth units per metre (0: the camera's, TUM 5000; ORB-SLAM2's TUM2.yaml uses 5208 for fr2) - "
                  "for calibration ablations");
  run->add_option("--local-ba", a.local_ba,
                  "localmap: the mapper's local bundle adjustment (poses and points); off for ablations")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  run->add_option("--map-lock", a.map_lock,
                  "localmap: pi (the map lock inherits a waiting real-time tracker's priority) | plain (to compare)")
      ->check(CLI::IsMember({"pi", "plain"}))->capture_default_str();
  run->add_option("--tracking-policy", a.tracking_policy,
                  "realtime mode: scheduling of the tracking thread - off (as created) | nice | rr | fifo "
                  "(slam-server's and quad-control's real-time path)")
      ->check(CLI::IsMember({"off", "nice", "rr", "fifo"}))->capture_default_str();
  std::string gt, est;
  auto* score = app.add_subcommand("score", "print ATE/RPE of EST against GT as JSON (TUM definitions, 20 ms association)");
  score->add_option("--gt", gt, "ground truth, TUM format")->required();
  score->add_option("--est", est, "estimate, TUM format")->required();
  std::vector<std::string> vocab_datasets;
  std::string vocab_out;
  slam::VocabularyOptions vocab_options;
  auto* vocab = app.add_subcommand("vocab", "train the ORB bag-of-words vocabulary on TUM folders (deterministic)");
  vocab->add_option("--dataset", vocab_datasets, "TUM folder(s) whose frames are the training images")->required();
  vocab->add_option("--out", vocab_out, "vocabulary file to write")->required();
  vocab->add_option("--branching", vocab_options.branching, "k")->capture_default_str();
  vocab->add_option("--levels", vocab_options.levels, "L")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    if (*run) return run_command(a);
    if (*vocab) return vocab_command(vocab_datasets, vocab_out, vocab_options);
    return slam::eval::run_score_command(gt, est, std::cout, std::cerr);
  } catch (const std::exception& e) {
    std::cerr << "slam-eval: " << e.what() << "\n";
    return 1;
  }
}
