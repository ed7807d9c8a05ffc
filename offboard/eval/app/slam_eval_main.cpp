// slam-eval: runs the SLAM engine on a TUM RGB-D folder and scores it, or scores a trajectory.
//   slam-eval run --dataset DIR [--features sift|surf|orb] [--backend vo|llc|glc] [--rate K]
//                 [--mode wait|realtime|sequential] --out DIR
//     writes DIR/trajectory.tum (final: each frame anchored to its optimised keyframe),
//     DIR/trajectory_online.tum (poses as estimated at the time), DIR/metrics.json, DIR/map.ply,
//     and for the thesis back-ends DIR/graph_before.g2o, DIR/graph_after.g2o; progress on stderr.
//   slam-eval score --gt GT.txt --est EST.tum    prints the ATE/RPE JSON.
//   slam-eval accel-check --dataset DIR [--dataset DIR2]   checks the accelerometer-to-camera
//     rotation against the ground truth (spread of the specific force's world direction), JSON.
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
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "rgbdquad/eval/metrics.hpp"
#include "slam/dataset/replay_schedule.hpp"
#include "slam/dataset/tum_dataset.hpp"
#include "slam/motion/accel_gate.hpp"
#include "slam/motion/gravity_consistency.hpp"
#include "slam/pipeline/map_export.hpp"
#include "slam/pipeline/pipeline.hpp"
#include "slam/report/run_metrics.hpp"
#include "slam/report/run_tables.hpp"

namespace slam = rgbdquad::slam;
namespace eval = rgbdquad::eval;

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct RunArgs {
  std::string dataset, out, features = "orb", backend = "localmap", mode = "wait", camera = "auto";
  std::string ransac = "random", keyframe_policy = "ransac";
  int cv_threads = -1;
  int orb_features = 0, orb_levels = 0;
  int orb_spread = slam::PipelineOptions{}.local_map_orb_spread_oversample;
  double orb_scale_factor = 0;
  int rate = 1, max_frames = 0, map_stride = 8, sift_first_octave = 0, max_features = 0;
  std::uint64_t seed = 20260101;
  bool no_undistort = false, no_map = false, quiet = false, no_reprojection = false;
  std::string stamp = "auto";
  std::string save_map, load_map;
  std::string record_lock_schedule, replay_lock_schedule;
  double withhold_from_s = -1, withhold_s = 0;
  std::string keyframe_gate = slam::PipelineOptions{}.keyframe_gate_mapper_busy ? "on" : "off";
  std::string loop_closing = slam::PipelineOptions{}.loop_closing ? "on" : "off",
              keyframe_new_content = "on", depth_noise = "keypoint", map_lock = "pi",
              tracking_policy = "off", local_ba = "on", cross_check = "on",
              restart_when_lost = slam::TrackerOptions{}.restart_when_lost ? "on" : "off",
              align_depth_time = slam::TrackerOptions{}.align_depth_time ? "on" : "off",
              confirm_off_path = slam::TrackerOptions{}.confirm_off_path ? "on" : "off",
              orb_pixel_centres = "on",
              depthless_observations = slam::PipelineOptions{}.depthless_observations();
  double depth_units_per_m = 0;
  double max_depth_m = slam::FeatureOptions{}.max_depth_m;
  double colour_stamp_lag_s = slam::TrackerOptions{}.colour_stamp_lag_s;
  std::string rolling_shutter = "on";     ///< on: track with the camera model's readout
  double rolling_shutter_readout_s = -1;  ///< >= 0: this readout instead (on or off)
  double rolling_shutter_angular_accel =
      slam::TrackerOptions{}.rolling_shutter_angular_accel_rad_per_s2;
  std::string gravity = slam::TrackerOptions{}.gravity.enabled ? "on" : "off";
  std::string gravity_accelerometer =
      slam::TrackerOptions{}.gravity.from_accelerometer ? "on" : "off";
  int mapping_rt_priority = slam::PipelineOptions{}.mapping_rt_priority;
};

/// Resident set size of this process, MiB (Linux /proc; -1 when unavailable). Instrumentation.
double rss_mib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return -1;
}

std::string guess_camera(const std::string& folder) {
  const std::string name =
      fs::path(folder).lexically_normal().filename().string() + fs::absolute(folder).string();
  if (name.find("fr2") != std::string::npos || name.find("freiburg2") != std::string::npos)
    return "fr2";
  if (name.find("fr3") != std::string::npos || name.find("freiburg3") != std::string::npos)
    return "fr3";
  return "fr1";
}

/// The pipeline options the command line asks for; nullopt with *err set on an unknown name.
std::optional<slam::PipelineOptions> pipeline_options(const RunArgs& a, std::string* err) {
  slam::PipelineOptions po;
  if (!slam::parse_detector_kind(a.features, &po.frontend.features.kind, err) ||
      !slam::parse_backend_kind(a.backend, &po.backend.kind, err) ||
      !slam::parse_pipeline_mode(a.mode, &po.mode, err)) {
    return std::nullopt;
  }
  po.frontend.features.undistort = !a.no_undistort;
  po.reprojection_refine = !a.no_reprojection;
  po.frontend.features.sift_upsample_first_octave = a.sift_first_octave < 0;
  po.frontend.features.sift_max_features = a.max_features;
  if (a.orb_features > 0) po.frontend.features.orb_features = a.orb_features;
  if (a.orb_levels > 0) po.frontend.features.orb_levels = a.orb_levels;
  if (a.orb_scale_factor > 0) po.frontend.features.orb_scale_factor = a.orb_scale_factor;
  po.frontend.features.max_depth_m = a.max_depth_m;
  po.local_map_orb_spread_oversample = a.orb_spread;
  po.frontend.seed = a.seed;
  po.loop_closing = a.loop_closing == "on";
  po.keyframe_gate_mapper_busy = a.keyframe_gate == "on";
  po.tracker.keyframe_needs_new_content = a.keyframe_new_content == "on";
  if (a.cross_check == "off") po.tracker.cross_check_tracked_ratio = 0;
  po.tracker.restart_when_lost = a.restart_when_lost == "on";
  po.tracker.align_depth_time = a.align_depth_time == "on";
  po.tracker.colour_stamp_lag_s = a.colour_stamp_lag_s;
  // The camera's own readout is set once the camera is known (rolling_shutter_readout_s()).
  if (a.rolling_shutter_readout_s >= 0)
    po.tracker.rolling_shutter_readout_s = a.rolling_shutter_readout_s;
  po.tracker.rolling_shutter_angular_accel_rad_per_s2 = a.rolling_shutter_angular_accel;
  po.tracker.gravity.enabled = a.gravity == "on";
  po.tracker.gravity.from_accelerometer = a.gravity_accelerometer == "on";
  po.tracker.confirm_off_path = a.confirm_off_path == "on";
  po.set_depthless_observations(a.depthless_observations);
  po.frontend.features.orb_pixel_centres = a.orb_pixel_centres == "on";
  po.map_lock_priority_inheritance = a.map_lock == "pi";
  po.mapper.bundle_adjustment = a.local_ba == "on";
  po.mapping_rt_priority = a.mapping_rt_priority;
  if (!slam::parse_thread_policy(a.tracking_policy, &po.tracking_thread_policy, err) ||
      !slam::parse_depth_noise_model(a.depth_noise, &po.depth_noise, err)) {
    return std::nullopt;
  }
  if ((!a.record_lock_schedule.empty() || !a.replay_lock_schedule.empty()) &&
      po.mode != slam::PipelineMode::kLive) {
    // Live mode tracks every frame it is given: a replay is given exactly the recorded run's.
    *err = "--record-lock-schedule and --replay-lock-schedule need --mode live";
    return std::nullopt;
  }
  po.lock_schedule_record_path = a.record_lock_schedule;
  po.lock_schedule_replay_path = a.replay_lock_schedule;
  po.backend.seed = a.seed + 1;
  const auto sampling =
      a.ransac == "thesis" ? slam::RansacSampling::kThesis : slam::RansacSampling::kRandom;
  po.frontend.ransac.sampling = sampling;
  po.backend.ransac.sampling = sampling;
  po.backend.keyframes.policy = a.keyframe_policy == "fixed" ? slam::KeyframePolicy::kFixedRate
                                                             : slam::KeyframePolicy::kRansac;
  return po;
}

/// The rolling-shutter readout the run tracks with: the command line's, else with
/// --rolling-shutter on the camera model's (protocol/camera/tum_cameras.json), else 0 (a global
/// shutter).
double rolling_shutter_readout_s(const RunArgs& a, const std::string& camera) {
  if (a.rolling_shutter_readout_s >= 0) return a.rolling_shutter_readout_s;
  if (a.rolling_shutter != "on") return 0.0;
  const rgbdquad::camera::TumCamera* model = rgbdquad::camera::find_tum_camera(camera);
  return model ? model->rolling_shutter_readout_s : 0.0;
}

/// The options a run used, the first keys of its metrics.json.
json run_options_json(const RunArgs& a, const std::string& camera, const std::string& stamp,
                      const slam::Intrinsics& intr) {
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
  m["cross_check"] = a.cross_check;
  m["restart_when_lost"] = a.restart_when_lost;
  m["align_depth_time"] = a.align_depth_time;
  m["colour_stamp_lag_s"] = a.colour_stamp_lag_s;
  m["rolling_shutter"] = a.rolling_shutter;
  m["rolling_shutter_readout_s"] = rolling_shutter_readout_s(a, camera);
  m["rolling_shutter_angular_accel_rad_per_s2"] = a.rolling_shutter_angular_accel;
  m["gravity"] = a.gravity;
  m["gravity_accelerometer"] = a.gravity_accelerometer;
  m["confirm_off_path"] = a.confirm_off_path;
  m["orb_pixel_centres"] = a.orb_pixel_centres;
  m["orb_spread"] = a.orb_spread;
  m["depth_noise"] = a.depth_noise;
  m["map_lock"] = a.map_lock;
  m["local_ba"] = a.local_ba;
  m["depth_units_per_m"] = intr.depth_units_per_m;
  m["max_depth_m"] = a.max_depth_m;
  m["depthless_observations"] = a.depthless_observations;
  m["tracking_policy"] = a.tracking_policy;
  m["mapping_rt_priority"] = a.mapping_rt_priority;
  return m;
}

/// Writes the trajectories, the pose graphs, the map (unless --no-map; its point count goes into
/// run->exported_map_points) and the saved map (--save-map).
bool write_run_outputs(const RunArgs& a, const slam::Pipeline& pipeline,
                       const slam::Intrinsics& intr, slam::RunOutcome* run, std::string* err) {
  const fs::path out(a.out);
  if (!eval::write_tum_trajectory((out / "trajectory.tum").string(), run->final_trajectory, err) ||
      !eval::write_tum_trajectory((out / "trajectory_online.tum").string(), run->online_trajectory,
                                  err))
    return false;
  const slam::BackEnd* be = pipeline.backend();  // the thesis systems' pose graph
  if (be && (!slam::write_text_file((out / "graph_before.g2o").string(),
                                    be->graph_before_optimisation().to_g2o(), err) ||
             !slam::write_text_file((out / "graph_after.g2o").string(), be->graph().to_g2o(), err)))
    return false;
  if (!a.no_map) {
    slam::MapExportOptions mo;
    mo.pixel_stride = a.map_stride;
    const std::string ply = (out / "map.ply").string();
    const long map_points = pipeline.is_local_map()
                                ? slam::write_map_points_ply(ply, *pipeline.local_map(), err)
                                : slam::write_keyframe_map_ply(ply, *be, intr, mo, err);
    if (map_points < 0) return false;
    run->exported_map_points = map_points;
  }
  if (!a.save_map.empty()) {
    if (!pipeline.save_map(a.save_map, err)) return false;
    std::cerr << "slam-eval: map saved to " << a.save_map << "\n";
  }
  return true;
}

/// What a run is set up with: options, camera, pose stamp, the open dataset and the pipeline.
struct RunSetup {
  slam::PipelineOptions po;
  std::string camera, stamp;
  slam::Intrinsics intr;
  std::optional<slam::TumDataset> ds;
  std::unique_ptr<slam::Pipeline> pipeline;
  /// Judges each frame's accelerometer sample (accelerometer.txt) at load; its counters go into
  /// metrics.json "accelerometer".
  slam::AccelGate accel_gate;
};

/// Options, intrinsics, dataset, output folder and pipeline (with --load-map); nullopt with the
/// exit code in *exit_code (2: bad options or map, 1: unreadable input or output) and the cause
/// on stderr.
std::optional<RunSetup> set_up_run(const RunArgs& a, int* exit_code) {
  std::string err;
  auto fail = [&](int code, const std::string& why) -> std::optional<RunSetup> {
    std::cerr << "slam-eval: " << why << "\n";
    *exit_code = code;
    return std::nullopt;
  };
  RunSetup r;
  const std::optional<slam::PipelineOptions> options = pipeline_options(a, &err);
  if (!options) return fail(2, err);
  r.po = *options;
  r.camera = a.camera == "auto" ? guess_camera(a.dataset) : a.camera;
  if (!slam::Intrinsics::from_name(r.camera, &r.intr, &err)) return fail(2, err);
  r.po.tracker.rolling_shutter_readout_s = rolling_shutter_readout_s(a, r.camera);
  if (a.depth_units_per_m > 0) r.intr.depth_units_per_m = a.depth_units_per_m;
  slam::TumDatasetOptions dso;
  dso.rate_divisor = a.rate;
  dso.max_frames = a.max_frames;
  // auto: the local map's poses rest on pixel measurements in the colour image, so they carry its
  // time (ORB-SLAM2's rgbd_tum does the same); the thesis back-ends align 3D points from the depth
  // image, so they carry the depth time (RGBD-SLAM's convention, which the thesis follows).
  r.stamp = a.stamp != "auto"
                ? a.stamp
                : (r.po.backend.kind == slam::BackendKind::kLocalMap ? "rgb" : "depth");
  dso.stamp_from_depth = r.stamp == "depth";
  r.ds = slam::TumDataset::open(a.dataset, dso, &err);
  if (!r.ds) return fail(1, err);
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (!fs::is_directory(a.out)) return fail(1, "cannot create output folder '" + a.out + "'");
  r.pipeline = slam::Pipeline::create(r.po, r.intr, &err);
  if (!r.pipeline) return fail(2, err);
  if (!a.load_map.empty() && !r.pipeline->load_map(a.load_map, &err)) return fail(2, err);
  return r;
}

/// What the replay loop measured besides what the pipeline reports.
struct ReplayStats {
  double wall_s = 0;
  std::size_t withheld = 0;
  double first_stamp_s = -1;
  slam::RssSamples rss_samples;  ///< every 30 frames
};

/// Submits every frame of the dataset, paced at the recorded rate in realtime/live mode (the
/// application boundary: the only place that reads the clock), withholding --withhold-s of it;
/// waits for the pipeline to finish. nullopt when the input is unreadable (the first frame, or more
/// than 5 frames).
std::optional<ReplayStats> replay_dataset(const RunArgs& a, RunSetup& r) {
  slam::TumDataset& ds = *r.ds;
  slam::Pipeline& pipeline = *r.pipeline;
  // A lock-step replay is paced by its record, not by the clock.
  const bool paced =
      (r.po.mode == slam::PipelineMode::kRealtime || r.po.mode == slam::PipelineMode::kLive) &&
      a.replay_lock_schedule.empty();
  const auto wall0 = std::chrono::steady_clock::now();
  const slam::ReplaySchedule schedule{ds.frame_period_s(), a.withhold_from_s, a.withhold_s};
  ReplayStats stats;
  std::size_t load_failures = 0;
  std::string err;
  for (std::size_t i = 0; i < ds.size(); ++i) {
    auto frame = ds.load(i, &err, &r.accel_gate);
    if (!frame) {
      std::cerr << "slam-eval: " << err << "\n";
      if (i == 0 || ++load_failures > 5) {
        pipeline.finish();
        std::cerr << "slam-eval: giving up on unreadable input\n";
        return std::nullopt;
      }
      continue;
    }
    if (paced)
      std::this_thread::sleep_until(wall0 + schedule.due(i));  // frame i is due i periods in
    const double stamp_s = frame->stamp_s;
    if (stats.first_stamp_s < 0) stats.first_stamp_s = stamp_s;
    if (schedule.withheld(stamp_s, stats.first_stamp_s)) {
      ++stats.withheld;  // a stalled link: the frame never reaches SLAM
      continue;
    }
    pipeline.submit(std::move(*frame));
    if (i % 30 == 0) stats.rss_samples.emplace_back(stamp_s, rss_mib());
    if (!a.quiet && ((i + 1) % 25 == 0 || i + 1 == ds.size()))
      std::cerr << "slam-eval: submitted " << (i + 1) << "/" << ds.size() << "\n";
  }
  pipeline.finish();
  stats.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return stats;
}

/// metrics.json "accelerometer": the file read (null without one), samples in it, and per frame
/// loaded the gate's verdict: used, ignored, and ignored per reason.
json accel_metrics_json(const slam::TumDataset& ds, const slam::AccelGate& gate) {
  const slam::AccelCounts& c = gate.counts();
  json by_reason = json::object();
  for (std::size_t v = 1; v < slam::kAccelVerdictCount; ++v)
    by_reason[slam::to_string(static_cast<slam::AccelVerdict>(v))] = c.by_verdict[v];
  json m;
  m["file"] = ds.accelerometer_path().empty() ? json(nullptr) : json(ds.accelerometer_path());
  m["samples_in_file"] = ds.accel_sample_count();
  m["frames_used"] = c.accepted();
  m["frames_ignored"] = c.ignored();
  m["ignored_by_reason"] = by_reason;
  m["max_stamp_gap_s"] = gate.options().max_stamp_gap_s;
  return m;
}

/// metrics.json (options, outcome, scores against the ground truth when the dataset has one).
bool write_metrics(const RunArgs& a, const RunSetup& r, const slam::RunOutcome& run, json* m,
                   std::string* err) {
  *m = run_options_json(a, r.camera, r.stamp, r.intr);
  std::string warning;
  slam::add_run_metrics(run, r.ds->groundtruth_path(), m, &warning);
  if (!warning.empty()) std::cerr << "slam-eval: " << warning << "\n";
  if (r.ds->groundtruth_path().empty()) {
    std::cerr << "slam-eval: no groundtruth.txt in " << a.dataset << ": trajectory not scored\n";
    (*m)["ground_truth"] = nullptr;
  }
  (*m)["accelerometer"] = accel_metrics_json(*r.ds, r.accel_gate);
  // attitude.txt (a replayed flight's attitude prior): the file read and the frames that got one.
  (*m)["attitude"] = {
      {"file", r.ds->attitude_path().empty() ? json(nullptr) : json(r.ds->attitude_path())},
      {"frames", r.ds->attitude_frames()}};
  std::ofstream mf(fs::path(a.out) / "metrics.json");
  mf << m->dump(2) << "\n";
  if (!mf) *err = "cannot write metrics.json";
  return static_cast<bool>(mf);
}

int run_command(const RunArgs& a) {
  if (a.cv_threads >= 0) cv::setNumThreads(a.cv_threads);
  int exit_code = 0;
  std::optional<RunSetup> setup = set_up_run(a, &exit_code);
  if (!setup) return exit_code;
  std::cerr << "slam-eval: " << setup->ds->size() << " frames from " << a.dataset << " (camera "
            << setup->camera << ", features " << a.features << ", backend " << a.backend
            << ", mode " << a.mode << ", rate 1/" << a.rate << ", ransac " << a.ransac
            << ", keyframes " << a.keyframe_policy << ")\n";
  const std::optional<ReplayStats> replay = replay_dataset(a, *setup);
  if (!replay) return 1;

  slam::RunOutcome run = slam::collect_run_outcome(*setup->pipeline);
  run.glc_backend = setup->po.backend.kind == slam::BackendKind::kGlc;
  run.wall_s = replay->wall_s;
  run.frames_withheld = replay->withheld;
  run.first_stamp_s = replay->first_stamp_s;
  run.withhold_from_s = a.withhold_from_s;
  run.withhold_s = a.withhold_s;
  std::string err;
  json m;
  // Trajectories, graphs, map; the per-frame and per-keyframe tables for long-run analysis
  // (offboard/bench/tools/longrun.py); metrics.json.
  if (!write_run_outputs(a, *setup->pipeline, setup->intr, &run, &err) ||
      !slam::write_run_tables(a.out, run.records, run.mapper_stats, run.loop_stats,
                              replay->rss_samples, &err) ||
      !write_metrics(a, *setup, run, &m, &err)) {
    std::cerr << "slam-eval: " << err << "\n";
    return 1;
  }
  std::cerr << "slam-eval: " << run.records.size() << " frames, " << run.summary.keyframes
            << " keyframes, " << run.summary.loop_closures << " loop closures, " << replay->wall_s
            << " s";
  if (m.contains("ate_rmse_m"))
    std::cerr << ", ATE " << m["ate_rmse_m"].get<double>() << " m, RPE "
              << m.value("rpe_trans_rmse_mm", 0.0) << " mm / " << m.value("rpe_rot_rmse_deg", 0.0)
              << " deg";
  const slam::AccelCounts& ac = setup->accel_gate.counts();
  std::cerr << "\nslam-eval: accelerometer: " << ac.accepted() << " frames used, " << ac.ignored()
            << " ignored (";
  for (std::size_t v = 1; v < slam::kAccelVerdictCount; ++v)
    std::cerr << (v > 1 ? ", " : "") << slam::to_string(static_cast<slam::AccelVerdict>(v)) << " "
              << ac.by_verdict[v];
  std::cerr << ")" << (setup->ds->accelerometer_path().empty() ? ", no accelerometer.txt" : "");
  if (!run.summary.lock_schedule.empty()) std::cerr << "\nslam-eval: " << run.summary.lock_schedule;
  if (!setup->ds->attitude_path().empty())
    std::cerr << "\nslam-eval: attitude.txt: " << setup->ds->attitude_frames() << " of "
              << setup->ds->size() << " frames carry an attitude";
  std::cerr << "\nslam-eval: wrote " << a.out << "/{trajectory.tum,trajectory_online.tum,"
            << (a.no_map ? "" : "map.ply,") << "metrics.json"
            << (setup->pipeline->is_local_map() ? "" : ",graph_before.g2o,graph_after.g2o")
            << "}\n";
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
  std::cerr << "slam-eval vocab: " << images.size() << " images, " << descriptors
            << " descriptors -> " << v->words() << " words (k " << options.branching << ", L "
            << options.levels << "), " << bytes.size() << " bytes to " << out << "\n";
  return 0;
}

/// The ground-truth pose nearest stamp_s within the benchmark's 20 ms; `sorted` by stamp.
const eval::StampedPose* nearest_pose(const eval::Trajectory& sorted, double stamp_s) {
  auto it = std::lower_bound(sorted.begin(), sorted.end(), stamp_s,
                             [](const eval::StampedPose& p, double t) { return p.stamp_s < t; });
  const eval::StampedPose* best = it != sorted.end() ? &*it : nullptr;
  if (it != sorted.begin() && (!best || stamp_s - std::prev(it)->stamp_s < best->stamp_s - stamp_s))
    best = &*std::prev(it);
  if (!best || std::abs(best->stamp_s - stamp_s) > eval::kDefaultMaxDtS) return nullptr;
  return best;
}

json spread_json(const std::array<double, 9>& R, const slam::GravitySpread& s) {
  return {{"R_cam_accel", R},
          {"rms_deg", s.rms_deg},
          {"p95_deg", s.p95_deg},
          {"max_deg", s.max_deg},
          {"mean_direction_world",
           {s.mean_direction_world.x(), s.mean_direction_world.y(), s.mean_direction_world.z()}}};
}

/// One dataset of `accel-check`: every frame whose accelerometer sample passes the gate and that
/// has a ground-truth pose within 20 ms; the spread for the configured rotation and for each of
/// the 24 axis-aligned candidates. nullopt (reason in *err) when the folder lacks a file.
std::optional<json> accel_check_dataset(const std::string& dir, std::string* err) {
  slam::TumDatasetOptions dso;
  dso.stamp_from_depth = false;
  const auto ds = slam::TumDataset::open(dir, dso, err);
  if (!ds) return std::nullopt;
  if (ds->accelerometer_path().empty() || ds->groundtruth_path().empty()) {
    *err = "'" + dir + "' needs accelerometer.txt and groundtruth.txt";
    return std::nullopt;
  }
  auto gt = eval::read_tum_trajectory(ds->groundtruth_path(), err);
  if (!gt) return std::nullopt;
  std::sort(gt->begin(), gt->end(),
            [](const auto& a, const auto& b) { return a.stamp_s < b.stamp_s; });
  slam::AccelGate gate;  // the defaults: the Kinect v1 model of protocol/camera/tum_cameras.json
  std::vector<Eigen::Matrix3d> R_world_cam;
  std::vector<Eigen::Vector3d> f_sensor;
  for (std::size_t i = 0; i < ds->size(); ++i) {
    const slam::TumEntry& e = ds->entry(i);
    if (gate.check(e.rgb_stamp_s, e.accel) != slam::AccelVerdict::kAccepted) continue;
    const eval::StampedPose* pose = nearest_pose(*gt, e.rgb_stamp_s);
    if (!pose) continue;
    R_world_cam.push_back(pose->T_world_cam.rotation());
    f_sensor.push_back(e.accel->f_sensor_mps2);
  }
  auto spread_for = [&](const std::array<double, 9>& R) {
    const Eigen::Matrix3d M =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R.data());
    std::vector<Eigen::Vector3d> f_cam;
    for (const Eigen::Vector3d& f : f_sensor) f_cam.push_back(M * f);
    return slam::gravity_direction_spread(R_world_cam, f_cam);
  };
  const auto configured = spread_for(gate.options().R_cam_sensor);
  if (!configured) {
    *err = "'" + dir + "': fewer than 2 frames with an accepted sample and a ground-truth pose";
    return std::nullopt;
  }
  std::vector<std::pair<double, std::array<double, 9>>> ranked;
  for (const auto& R : slam::axis_aligned_rotations()) {
    const auto s = spread_for(R);
    if (s) ranked.emplace_back(s->rms_deg, R);
  }
  std::sort(ranked.begin(), ranked.end());
  const std::size_t rank =
      1 + static_cast<std::size_t>(std::count_if(ranked.begin(), ranked.end(), [&](const auto& r) {
        return r.first < configured->rms_deg - 1e-12;
      }));
  json m;
  m["dataset"] = dir;
  m["frames"] = ds->size();
  m["frames_checked"] = configured->samples;
  m["ignored_by_gate"] = gate.counts().ignored();
  m["configured"] = spread_json(gate.options().R_cam_sensor, *configured);
  m["configured_rank_of_24"] = rank;
  m["best_candidate"] = spread_json(ranked.front().second, *spread_for(ranked.front().second));
  if (ranked.size() > 1)
    m["second_candidate"] = spread_json(ranked[1].second, *spread_for(ranked[1].second));
  return m;
}

/// `accel-check`: prints a JSON array, one object per dataset; 1 when a folder cannot be used.
int accel_check_command(const std::vector<std::string>& datasets) {
  json out = json::array();
  for (const std::string& dir : datasets) {
    std::string err;
    const auto m = accel_check_dataset(dir, &err);
    if (!m) {
      std::cerr << "slam-eval accel-check: " << err << "\n";
      return 1;
    }
    out.push_back(*m);
  }
  std::cout << out.dump(2) << "\n";
  return 0;
}

/// `run`: the dataset, the output, the system and its front-end, the frames taken.
void add_dataset_and_system_options(CLI::App* run, RunArgs& a) {
  run->add_option("--dataset", a.dataset,
                  "TUM folder (rgb.txt, depth.txt, optional groundtruth.txt)")
      ->required();
  run->add_option("--out", a.out, "output folder (created)")->required();
  run->add_option("--features", a.features, "sift | surf | orb (orb keeps up at 30 fps)")
      ->check(CLI::IsMember({"sift", "surf", "orb"}))
      ->capture_default_str();
  run->add_option(
         "--backend", a.backend,
         "localmap (tracking against a local map + local mapping: the system that flies) | "
         "vo | llc | glc (the thesis back-ends)")
      ->check(CLI::IsMember({"localmap", "vo", "llc", "glc"}))
      ->capture_default_str();
  run->add_option("--rate", a.rate, "keep every K-th frame (frame-rate reduction 1/K)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  run->add_option(
         "--mode", a.mode,
         "wait (deterministic) | realtime (paced, newest frame wins) | live (paced, every frame "
         "tracked on the submitting thread, as slam-server) | sequential (one thread)")
      ->check(CLI::IsMember({"wait", "realtime", "live", "sequential"}))
      ->capture_default_str();
  run->add_option("--camera", a.camera, "intrinsics: auto (from folder name) | fr1 | fr2 | fr3")
      ->check(CLI::IsMember({"auto", "fr1", "fr2", "fr3"}))
      ->capture_default_str();
  run->add_option("--ransac", a.ransac,
                  "random (seeded, adaptive) | thesis (4 best pairs, 10 tries)")
      ->check(CLI::IsMember({"random", "thesis"}))
      ->capture_default_str();
  run->add_option("--keyframes", a.keyframe_policy,
                  "ransac (thesis default) | fixed (3 per second)")
      ->check(CLI::IsMember({"ransac", "fixed"}))
      ->capture_default_str();
  run->add_option("--max-frames", a.max_frames, "stop after N frames (0 = all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  run->add_option("--seed", a.seed, "RANSAC seed")->capture_default_str();
  run->add_option("--map-stride", a.map_stride, "PLY map: every N-th pixel")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  run->add_option("--sift-first-octave", a.sift_first_octave,
                  "-1: OpenCV's upsampled first octave; 0: start at input resolution (~4x faster)")
      ->check(CLI::IsMember({-1, 0}))
      ->capture_default_str();
  run->add_option("--max-features", a.max_features, "SIFT: keep the N strongest (0 = all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  run->add_option(
         "--stamp", a.stamp,
         "pose time: auto (rgb for localmap, whose poses rest on colour-image pixels; depth for "
         "vo/llc/glc, which align depth-image points) | depth | rgb")
      ->check(CLI::IsMember({"auto", "depth", "rgb"}))
      ->capture_default_str();
}

/// `run`: front-end switches, a stalled link, map files, ORB pyramid, progress.
void add_frontend_and_map_file_options(CLI::App* run, RunArgs& a) {
  run->add_flag("--no-reprojection-refine", a.no_reprojection,
                "skip the Gauss-Newton reprojection refinement after RANSAC");
  run->add_option("--cv-threads", a.cv_threads,
                  "OpenCV worker threads (-1 = OpenCV default; 1 makes *_cpu timings complete)")
      ->capture_default_str();
  run->add_flag("--no-undistort", a.no_undistort,
                "use keypoints as detected (default: undistort them with the camera's coefficients "
                "before lifting to 3D)");
  run->add_flag("--no-map", a.no_map, "do not write map.ply");
  run->add_option("--withhold", a.withhold_s,
                  "seconds of frames withheld (a stalled link), see --withhold-from");
  run->add_option("--withhold-from", a.withhold_from_s,
                  "start of the withheld span, seconds after the first frame");
  run->add_option("--save-map", a.save_map, "localmap: write the final map to this file");
  run->add_option(
      "--load-map", a.load_map,
      "localmap: start from this saved map (relocalise in it; poses in its world frame)");
  run->add_option("--orb-features", a.orb_features,
                  "ORB feature count (0: default, thesis Table 4.3: 1024)");
  run->add_option("--orb-levels", a.orb_levels, "ORB pyramid levels (0: default, thesis: 6)");
  run->add_option("--orb-scale-factor", a.orb_scale_factor,
                  "ORB pyramid scale factor (0: default, thesis: 2)");
  run->add_option("--orb-spread", a.orb_spread,
                  "localmap, ORB: detect this many times the feature count and keep them spread "
                  "over the image per pyramid level (0 or 1: cv::ORB's strongest; docs/slam.md)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  run->add_option("--record-lock-schedule", a.record_lock_schedule,
                  "localmap, --mode live: record the order the SLAM threads took the map in, for "
                  "an exact replay (slam/core/lock_schedule.hpp)");
  run->add_option("--replay-lock-schedule", a.replay_lock_schedule,
                  "localmap, --mode live: replay such a record (the same frames, unpaced); "
                  "metrics.json lock_schedule says whether it was followed to the end")
      ->check(CLI::ExistingFile);
  run->add_flag("--quiet", a.quiet, "no per-25-frame progress");
}

/// `run`: the flying system's switches for ablations, and its real-time scheduling.
/// `run`: the gravity measurement and its sources (docs/slam.md, "Gravity on roll and pitch").
void add_gravity_options(CLI::App* run, RunArgs& a) {
  run->add_option("--gravity", a.gravity,
                  "localmap: gravity's direction (the frame's flight-controller attitude, else "
                  "the Kinect's accelerometer with --gravity-accelerometer on) on roll and pitch "
                  "in tracking, local BA and the loop-closing graph (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option(
         "--gravity-accelerometer", a.gravity_accelerometer,
         "localmap, with --gravity on: the Kinect's accelerometer as a gravity source when "
         "a frame carries no attitude (off: it measures the camera's acceleration too; "
         "docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
}

/// The depth sensor as the local map sees it: its noise model, scale and range.
void add_depth_ablation_options(CLI::App* run, RunArgs& a) {
  run->add_option(
         "--depth-noise", a.depth_noise,
         "localmap: sigma of the depth residual - kinect (the sensor's axial noise, Nguyen et al. "
         "2012) | "
         "keypoint (ORB-SLAM2: the keypoint's pixel sigma on the virtual-stereo disparity) | "
         "kinect-edge (kinect plus the depth image's slope times the keypoint's pixel sigma)")
      ->check(CLI::IsMember({"kinect", "keypoint", "kinect-edge"}))
      ->capture_default_str();
  run->add_option("--depth-units-per-m", a.depth_units_per_m,
                  "raw depth units per metre (0: the camera's, TUM 5000; ORB-SLAM2's TUM2.yaml "
                  "uses 5208 for fr2) - "
                  "for calibration ablations");
  run->add_option("--depthless-observations", a.depthless_observations,
                  "localmap: keypoints without a depth reading are matched to map points and "
                  "fitted as (u, v) observations (ORB-SLAM2's monocular keypoints; docs/slam.md); "
                  "map: keyframes also keep them and the mapper triangulates map points from them")
      ->check(CLI::IsMember({"on", "off", "map"}))
      ->capture_default_str();
  run->add_option("--max-depth-m", a.max_depth_m,
                  "features whose depth reading is farther than this are not used (m; the Kinect "
                  "v1's noise grows with the square of the depth; ORB-SLAM2 uses every reading)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

void add_ablation_options(CLI::App* run, RunArgs& a) {
  run->add_option("--keyframe-gate", a.keyframe_gate,
                  "localmap, realtime: ORB-SLAM2's c1b/c1c rule - while the mapper is busy only "
                  "weak tracking "
                  "makes a keyframe (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--loop-closing", a.loop_closing,
                  "localmap: loop closing on its own thread (ORB only: the vocabulary is ORB's)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--keyframe-new-content", a.keyframe_new_content,
                  "localmap: a view change makes no keyframe that would be culled as redundant at "
                  "once (>= 90 % of "
                  "its tracked near points seen by >= 3 keyframes); off: ORB-SLAM2's rule as is")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--restart-when-lost", a.restart_when_lost,
                  "localmap: a frame that can be neither tracked nor relocalised starts a new map "
                  "segment at the predicted pose instead of staying lost (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--confirm-off-path", a.confirm_off_path,
                  "localmap: a fit only the motion bound refuses is kept when a registration to "
                  "the reference keyframe lands on the same pose (docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--colour-stamp-lag-s", a.colour_stamp_lag_s,
                  "localmap, with --align-depth-time: how long after the colour exposure its "
                  "stamp was taken (s)")
      ->capture_default_str();
  run->add_option("--rolling-shutter", a.rolling_shutter,
                  "localmap: model the colour camera's rolling shutter with the camera model's "
                  "readout (fr1/fr2 0.024 s, fr3 0): each pose is fitted with the rate over the "
                  "readout; off: a global shutter (frames rendered by hil/tools/render_tum.py)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--rolling-shutter-readout-s", a.rolling_shutter_readout_s,
                  "localmap: this readout time instead, top row to bottom row (s; 0: a global "
                  "shutter), whatever --rolling-shutter says")
      ->check(CLI::Range(0.0, 0.1));
  run->add_option("--rolling-shutter-angular-accel", a.rolling_shutter_angular_accel,
                  "localmap: how fast the camera's rate changes (rad/s^2); the rolling-shutter "
                  "rate is held near the motion model's within this x the model's age; a "
                  "calibration run widens it (rolling_shutter_check.py)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  run->add_option("--align-depth-time", a.align_depth_time,
                  "localmap: re-time each depth image to its colour image by the predicted "
                  "rotation (the Kinect's depth is 3-11 ms older in TUM fr1; docs/slam.md)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--cross-check", a.cross_check,
                  "localmap: a weak fit (< 0.75 x the reference keyframe's tracked points, or < 50 "
                  "inliers) is cross-checked by registering the frame to the reference keyframe, "
                  "independent of the prediction; that fit replaces it when it has more inliers "
                  "at a different pose (> 1 cm or 0.5 deg away)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--orb-pixel-centres", a.orb_pixel_centres,
                  "ORB keypoints of pyramid level L > 0 moved to their corner's input pixel "
                  "(cv::ORB reports them (scale^L - 1) / 2 px up and left of it: 1.5 px at level "
                  "2 with scale 2); off for ablations")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option(
         "--local-ba", a.local_ba,
         "localmap: the mapper's local bundle adjustment (poses and points); off for ablations")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  run->add_option("--map-lock", a.map_lock,
                  "localmap: pi (the map lock inherits a waiting real-time tracker's priority) | "
                  "plain (to compare)")
      ->check(CLI::IsMember({"pi", "plain"}))
      ->capture_default_str();
  run->add_option(
         "--tracking-policy", a.tracking_policy,
         "realtime mode: scheduling of the tracking thread - off (as created) | nice | rr | fifo "
         "(slam-server's and quad-control's real-time path)")
      ->check(CLI::IsMember({"off", "nice", "rr", "fifo"}))
      ->capture_default_str();
  run->add_option("--mapping-rt-priority", a.mapping_rt_priority,
                  "realtime mode with a real-time tracking policy: SCHED_RR priority of the local "
                  "mapping thread, below tracking's 10 (0: normal policy, nice below tracking)")
      ->check(CLI::Range(0, 9))
      ->capture_default_str();
}

/// `score`: ATE/RPE of an estimate against ground truth.
struct ScoreArgs {
  std::string gt, est;
};

CLI::App* add_score_command(CLI::App& app, ScoreArgs& s) {
  auto* score = app.add_subcommand(
      "score", "print ATE/RPE of EST against GT as JSON (TUM definitions, 20 ms association)");
  score->add_option("--gt", s.gt, "ground truth, TUM format")->required();
  score->add_option("--est", s.est, "estimate, TUM format")->required();
  return score;
}

/// `vocab`: the ORB vocabulary trained on TUM folders.
struct VocabArgs {
  std::vector<std::string> datasets;
  std::string out;
  slam::VocabularyOptions options;
};

CLI::App* add_vocab_command(CLI::App& app, VocabArgs& v) {
  auto* vocab = app.add_subcommand(
      "vocab", "train the ORB bag-of-words vocabulary on TUM folders (deterministic)");
  vocab->add_option("--dataset", v.datasets, "TUM folder(s) whose frames are the training images")
      ->required();
  vocab->add_option("--out", v.out, "vocabulary file to write")->required();
  vocab->add_option("--branching", v.options.branching, "k")->capture_default_str();
  vocab->add_option("--levels", v.options.levels, "L")->capture_default_str();
  return vocab;
}

/// `accel-check`: the accelerometer rotation against TUM folders with ground truth.
CLI::App* add_accel_check_command(CLI::App& app, std::vector<std::string>& datasets) {
  auto* check = app.add_subcommand(
      "accel-check",
      "check the accelerometer-to-camera rotation on TUM folders with accelerometer.txt and "
      "groundtruth.txt: spread (degrees) of the specific force's direction in the mocap world, "
      "for the configured rotation and the 24 axis-aligned candidates; JSON on stdout");
  check->add_option("--dataset", datasets, "TUM folder(s)")->required();
  return check;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"slam-eval: run the RGB-D SLAM engine on a TUM folder and score it"};
  app.require_subcommand(1);
  RunArgs a;
  auto* run =
      app.add_subcommand("run", "run SLAM on a TUM RGB-D folder, write trajectory + metrics");
  add_dataset_and_system_options(run, a);
  add_frontend_and_map_file_options(run, a);
  add_ablation_options(run, a);
  add_depth_ablation_options(run, a);
  add_gravity_options(run, a);
  ScoreArgs s;
  add_score_command(app, s);
  VocabArgs v;
  CLI::App* vocab = add_vocab_command(app, v);
  std::vector<std::string> accel_datasets;
  CLI::App* accel_check = add_accel_check_command(app, accel_datasets);
  CLI11_PARSE(app, argc, argv);
  try {
    if (*run) return run_command(a);
    if (*accel_check) return accel_check_command(accel_datasets);
    if (*vocab) return vocab_command(v.datasets, v.out, v.options);
    return eval::run_score_command(s.gt, s.est, std::cout, std::cerr);
  } catch (const std::exception& e) {
    std::cerr << "slam-eval: " << e.what() << "\n";
    return 1;
  }
}
