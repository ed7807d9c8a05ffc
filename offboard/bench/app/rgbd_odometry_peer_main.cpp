// rgbd-odometry-peer: OpenCV contrib's dense photometric odometry (cv::rgbd::RgbdOdometry,
// Steinbruecker et al. 2011) on the same TUM frames as slam-eval, as a benchmark peer.
// Frame-to-frame, chained, default OpenCV parameters; writes OUT/trajectory.tum and
// OUT/metrics.json (ATE/RPE when ground truth exists, ms/frame median/mean).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>

#include "rgbdquad/eval/metrics.hpp"
#include "slam/dataset/tum_dataset.hpp"
#include "slam/thesis/frontend.hpp"

namespace slam = rgbdquad::slam;
namespace eval = rgbdquad::eval;
namespace fs = std::filesystem;

namespace {

/// The command line.
struct PeerOptions {
  std::string dataset, out, camera = "fr1";
  int rate = 1, max_frames = 0, cv_threads = 1;
};

void add_options(CLI::App& app, PeerOptions& o) {
  app.add_option("--dataset", o.dataset, "TUM folder")->required();
  app.add_option("--out", o.out, "output folder (created)")->required();
  app.add_option("--camera", o.camera, "fr1 | fr2 | fr3")
      ->check(CLI::IsMember({"fr1", "fr2", "fr3"}))
      ->capture_default_str();
  app.add_option("--rate", o.rate, "keep every K-th frame")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-frames", o.max_frames, "0 = all")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--cv-threads", o.cv_threads,
                 "OpenCV worker threads (1: CPU ms per frame is complete; -1 = OpenCV default)")
      ->capture_default_str();
}

/// What one replay produced: the chained trajectory, and per frame pair (from the second frame
/// on) the wall and thread-CPU milliseconds of conversion and odometry.
struct PeerRun {
  eval::Trajectory trajectory;
  std::vector<double> ms, cpu_ms;
  std::size_t failures = 0;  ///< frame pairs RgbdOdometry found no motion for (pose held)
};

/// OpenCV's 4x4 double Rt as an isometry.
Eigen::Isometry3d isometry_from(const cv::Mat& Rt) {
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = Rt.at<double>(r, c);
  return Eigen::Isometry3d(M);
}

/// Frame-to-frame odometry over the whole dataset, chained from the identity; false (with
/// `err`) when a frame cannot be loaded.
bool replay(const slam::TumDataset& ds, const slam::Intrinsics& k, PeerRun* run, std::string* err) {
  const cv::Mat K = (cv::Mat_<float>(3, 3) << k.fx_px, 0, k.cx_px, 0, k.fy_px, k.cy_px, 0, 0, 1);
  cv::Ptr<cv::rgbd::RgbdOdometry> odo = cv::rgbd::RgbdOdometry::create(K);
  cv::Mat prev_grey, prev_depth;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < ds.size(); ++i) {
    auto f = ds.load(i, err);
    if (!f) return false;
    const std::int64_t t0 = slam::steady_now_ns();
    const std::int64_t c0 = slam::thread_cpu_now_ns();
    cv::Mat grey, depth;
    cv::cvtColor(f->rgb, grey, cv::COLOR_BGR2GRAY);
    f->depth.convertTo(depth, CV_32F, 1.0 / k.depth_units_per_m);
    if (!prev_grey.empty()) {
      cv::Mat Rt;
      // Rt maps points of the source (previous) frame into the destination (current) frame.
      if (odo->compute(prev_grey, prev_depth, cv::Mat(), grey, depth, cv::Mat(), Rt) &&
          !Rt.empty()) {
        const Eigen::Isometry3d T_cur_prev = isometry_from(Rt);
        T_world_cam = T_world_cam * T_cur_prev.inverse();
      } else {
        ++run->failures;
      }
      run->ms.push_back(slam::ms_since(t0));
      run->cpu_ms.push_back((slam::thread_cpu_now_ns() - c0) * 1e-6);
    }
    prev_grey = grey;
    prev_depth = depth;
    run->trajectory.push_back({f->stamp_s, T_world_cam});
  }
  return true;
}

/// Median and mean milliseconds per frame (sorts the run's timings).
void add_timing(PeerRun& run, nlohmann::json& m) {
  std::sort(run.ms.begin(), run.ms.end());
  std::sort(run.cpu_ms.begin(), run.cpu_ms.end());
  if (!run.cpu_ms.empty()) m["cpu_ms_per_frame_median"] = run.cpu_ms[run.cpu_ms.size() / 2];
  if (!run.ms.empty()) {
    double s = 0;
    for (double x : run.ms) s += x;
    m["ms_per_frame_median"] = run.ms[run.ms.size() / 2];
    m["ms_per_frame_mean"] = s / static_cast<double>(run.ms.size());
  }
}

/// ATE and RPE against the dataset's ground truth, when it has one and they can be computed.
void add_accuracy(const std::string& groundtruth_path, const eval::Trajectory& traj,
                  nlohmann::json& m) {
  if (groundtruth_path.empty()) return;
  std::string err;
  const auto gt = eval::read_tum_trajectory(groundtruth_path, &err);
  if (!gt) return;
  if (auto ate = eval::compute_ate(*gt, traj, eval::kDefaultMaxDtS, &err)) {
    m["ate_rmse_m"] = ate->trans_rmse_m;
    m["ate_rot_rmse_deg"] = ate->rot_rmse_deg;
  }
  if (auto rpe = eval::compute_rpe(*gt, traj, eval::kDefaultMaxDtS, &err)) {
    m["rpe_trans_rmse_mm"] = rpe->trans_rmse_mm;
    m["rpe_rot_rmse_deg"] = rpe->rot_rmse_deg;
  }
}

/// Writes OUT/metrics.json and says the headline numbers on stderr.
void write_metrics(const PeerOptions& o, const slam::TumDataset& ds, PeerRun& run) {
  nlohmann::json m;
  m["peer"] = "cv::rgbd::RgbdOdometry (OpenCV 4.6 contrib, default parameters)";
  m["frames"] = run.trajectory.size();
  m["failures"] = run.failures;
  m["cv_threads"] = o.cv_threads;
  add_timing(run, m);
  add_accuracy(ds.groundtruth_path(), run.trajectory, m);
  std::ofstream(fs::path(o.out) / "metrics.json") << m.dump(2) << "\n";
  std::cerr << "rgbd-odometry-peer: " << run.trajectory.size() << " frames, " << run.failures
            << " failures, " << m.value("ate_rmse_m", -1.0) << " m ATE, "
            << m.value("ms_per_frame_median", -1.0) << " ms/frame median\n";
}

/// Says `why` on stderr; returns `exit_code`.
int fail(const std::string& why, int exit_code) {
  std::cerr << "rgbd-odometry-peer: " << why << "\n";
  return exit_code;
}

/// Replays the dataset and writes OUT/trajectory.tum and OUT/metrics.json; the exit code (2: an
/// unknown camera, 1: the dataset or the trajectory file failed).
int run_peer(const PeerOptions& o) {
  if (o.cv_threads >= 0) cv::setNumThreads(o.cv_threads);
  std::string err;
  slam::Intrinsics k;
  if (!slam::Intrinsics::from_name(o.camera, &k, &err)) return fail(err, 2);
  slam::TumDatasetOptions dataset_options;
  dataset_options.rate_divisor = o.rate;
  dataset_options.max_frames = o.max_frames;
  const auto ds = slam::TumDataset::open(o.dataset, dataset_options, &err);
  if (!ds) return fail(err, 1);
  fs::create_directories(o.out);
  PeerRun run;
  if (!replay(*ds, k, &run, &err)) return fail(err, 1);
  const std::string trajectory_path = (fs::path(o.out) / "trajectory.tum").string();
  if (!eval::write_tum_trajectory(trajectory_path, run.trajectory, &err)) return fail(err, 1);
  write_metrics(o, *ds, run);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rgbd-odometry-peer: cv::rgbd::RgbdOdometry on a TUM folder, scored like slam-eval"};
  PeerOptions options;
  add_options(app, options);
  CLI11_PARSE(app, argc, argv);
  return run_peer(options);
}
