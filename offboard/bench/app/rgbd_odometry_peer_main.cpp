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

int main(int argc, char** argv) {
  CLI::App app{"rgbd-odometry-peer: cv::rgbd::RgbdOdometry on a TUM folder, scored like slam-eval"};
  std::string dataset, out, camera = "fr1";
  int rate = 1, max_frames = 0, cv_threads = 1;
  app.add_option("--dataset", dataset, "TUM folder")->required();
  app.add_option("--out", out, "output folder (created)")->required();
  app.add_option("--camera", camera, "fr1 | fr2 | fr3")
      ->check(CLI::IsMember({"fr1", "fr2", "fr3"}))
      ->capture_default_str();
  app.add_option("--rate", rate, "keep every K-th frame")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-frames", max_frames, "0 = all")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--cv-threads", cv_threads,
                 "OpenCV worker threads (1: CPU ms per frame is complete; -1 = OpenCV default)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (cv_threads >= 0) cv::setNumThreads(cv_threads);

  std::string err;
  slam::Intrinsics k;
  if (!slam::Intrinsics::from_name(camera, &k, &err)) {
    std::cerr << "rgbd-odometry-peer: " << err << "\n";
    return 2;
  }
  slam::TumDatasetOptions o;
  o.rate_divisor = rate;
  o.max_frames = max_frames;
  auto ds = slam::TumDataset::open(dataset, o, &err);
  if (!ds) {
    std::cerr << "rgbd-odometry-peer: " << err << "\n";
    return 1;
  }
  fs::create_directories(out);
  const cv::Mat K = (cv::Mat_<float>(3, 3) << k.fx_px, 0, k.cx_px, 0, k.fy_px, k.cy_px, 0, 0, 1);
  cv::Ptr<cv::rgbd::RgbdOdometry> odo = cv::rgbd::RgbdOdometry::create(K);
  eval::Trajectory traj;
  std::vector<double> ms, cpu_ms;
  cv::Mat prev_grey, prev_depth;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  std::size_t failures = 0;
  for (std::size_t i = 0; i < ds->size(); ++i) {
    auto f = ds->load(i, &err);
    if (!f) {
      std::cerr << "rgbd-odometry-peer: " << err << "\n";
      return 1;
    }
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
        Eigen::Matrix4d M;
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) M(r, c) = Rt.at<double>(r, c);
        Eigen::Isometry3d T_cur_prev(M);
        T_world_cam = T_world_cam * T_cur_prev.inverse();
      } else {
        ++failures;
      }
      ms.push_back(slam::ms_since(t0));
      cpu_ms.push_back((slam::thread_cpu_now_ns() - c0) * 1e-6);
    }
    prev_grey = grey;
    prev_depth = depth;
    traj.push_back({f->stamp_s, T_world_cam});
  }
  if (!eval::write_tum_trajectory((fs::path(out) / "trajectory.tum").string(), traj, &err)) {
    std::cerr << "rgbd-odometry-peer: " << err << "\n";
    return 1;
  }
  nlohmann::json m;
  m["peer"] = "cv::rgbd::RgbdOdometry (OpenCV 4.6 contrib, default parameters)";
  m["frames"] = traj.size();
  m["failures"] = failures;
  std::sort(ms.begin(), ms.end());
  std::sort(cpu_ms.begin(), cpu_ms.end());
  if (!cpu_ms.empty()) m["cpu_ms_per_frame_median"] = cpu_ms[cpu_ms.size() / 2];
  m["cv_threads"] = cv_threads;
  if (!ms.empty()) {
    double s = 0;
    for (double x : ms) s += x;
    m["ms_per_frame_median"] = ms[ms.size() / 2];
    m["ms_per_frame_mean"] = s / static_cast<double>(ms.size());
  }
  if (!ds->groundtruth_path().empty()) {
    auto gt = eval::read_tum_trajectory(ds->groundtruth_path(), &err);
    if (gt) {
      if (auto ate = eval::compute_ate(*gt, traj, eval::kDefaultMaxDtS, &err)) {
        m["ate_rmse_m"] = ate->trans_rmse_m;
        m["ate_rot_rmse_deg"] = ate->rot_rmse_deg;
      }
      if (auto rpe = eval::compute_rpe(*gt, traj, eval::kDefaultMaxDtS, &err)) {
        m["rpe_trans_rmse_mm"] = rpe->trans_rmse_mm;
        m["rpe_rot_rmse_deg"] = rpe->rot_rmse_deg;
      }
    }
  }
  std::ofstream(fs::path(out) / "metrics.json") << m.dump(2) << "\n";
  std::cerr << "rgbd-odometry-peer: " << traj.size() << " frames, " << failures << " failures, "
            << m.value("ate_rmse_m", -1.0) << " m ATE, " << m.value("ms_per_frame_median", -1.0)
            << " ms/frame median\n";
  return 0;
}
