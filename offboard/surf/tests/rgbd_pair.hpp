// Real-motion check shared by the tests and surf-bench: match features between two frames of a
// TUM RGB-D sequence and count the matches that the ground-truth motion confirms. A keypoint of
// frame A is lifted with its depth (registered to the colour image), moved by
// T_cam_b^-1 T_cam_a from the motion-capture ground truth, and projected into frame B with the
// Freiburg 1 intrinsics and distortion; the match is consistent if it lands within tol_px.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/eval/metrics.hpp"

namespace rgbdquad::surf::testing {

/// Freiburg 1 colour camera (protocol/camera/tum_cameras.json).
struct Fr1Camera {
  static constexpr const rgbdquad::camera::TumCamera& kCam = rgbdquad::camera::kTumFr1;
  cv::Matx33d K{kCam.fx_px, 0.0, kCam.cx_px, 0.0, kCam.fy_px, kCam.cy_px, 0.0, 0.0, 1.0};
  cv::Vec<double, 5> distortion{kCam.distortion[0], kCam.distortion[1], kCam.distortion[2],
                                kCam.distortion[3], kCam.distortion[4]};
};

/// TUM depth PNGs store 5000 units per metre.
constexpr double kDepthUnitsPerMetre = rgbdquad::camera::kTumDepthUnitsPerM;
/// The benchmark's association window between rgb, depth and ground truth.
constexpr double kAssociationWindowS = 0.02;

struct RgbdFrame {
  double stamp_s = 0.0;
  cv::Mat gray;   ///< CV_8UC1
  cv::Mat depth;  ///< CV_16UC1, kDepthUnitsPerMetre per metre, 0 = no reading
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

struct StampedFile {
  double stamp_s;
  std::string path;
};

inline std::vector<StampedFile> read_file_list(const std::string& dir, const std::string& list) {
  std::vector<StampedFile> out;
  std::ifstream in(dir + "/" + list);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    StampedFile f{};
    if (fields >> f.stamp_s >> f.path) out.push_back({f.stamp_s, dir + "/" + f.path});
  }
  return out;
}

/// Ground-truth pose at `stamp_s`, interpolated (lerp + slerp) between the bracketing samples
/// when both are within kAssociationWindowS.
inline std::optional<Eigen::Isometry3d> pose_at(const eval::Trajectory& gt, double stamp_s) {
  for (std::size_t i = 0; i + 1 < gt.size(); ++i) {
    const auto& a = gt[i];
    const auto& b = gt[i + 1];
    if (a.stamp_s <= stamp_s && stamp_s <= b.stamp_s) {
      if (stamp_s - a.stamp_s > kAssociationWindowS || b.stamp_s - stamp_s > kAssociationWindowS)
        return std::nullopt;
      const double t =
          (b.stamp_s > a.stamp_s) ? (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s) : 0.0;
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = Eigen::Quaterniond(a.T_world_cam.rotation())
                       .slerp(t, Eigen::Quaterniond(b.T_world_cam.rotation()))
                       .toRotationMatrix();
      T.translation() = (1.0 - t) * a.T_world_cam.translation() + t * b.T_world_cam.translation();
      return T;
    }
  }
  return std::nullopt;
}

/// Loads the frames of a TUM sequence folder whose rgb has a depth image and a ground-truth pose
/// within kAssociationWindowS; stops after max_frames. Empty on missing files.
inline std::vector<RgbdFrame> load_rgbd_sequence(const std::string& dir, std::size_t max_frames) {
  std::vector<RgbdFrame> frames;
  std::string error;
  const auto gt = eval::read_tum_trajectory(dir + "/groundtruth.txt", &error);
  if (!gt) return frames;
  const auto depth_list = read_file_list(dir, "depth.txt");
  for (const auto& rgb : read_file_list(dir, "rgb.txt")) {
    if (frames.size() >= max_frames) break;
    const StampedFile* best = nullptr;
    for (const auto& d : depth_list) {
      if (std::abs(d.stamp_s - rgb.stamp_s) <= kAssociationWindowS &&
          (best == nullptr ||
           std::abs(d.stamp_s - rgb.stamp_s) < std::abs(best->stamp_s - rgb.stamp_s))) {
        best = &d;
      }
    }
    const auto pose = pose_at(*gt, rgb.stamp_s);
    if (best == nullptr || !pose) continue;
    RgbdFrame f;
    f.stamp_s = rgb.stamp_s;
    f.gray = cv::imread(rgb.path, cv::IMREAD_GRAYSCALE);
    f.depth = cv::imread(best->path, cv::IMREAD_UNCHANGED);
    f.T_world_cam = *pose;
    if (f.gray.empty() || f.depth.type() != CV_16UC1) continue;
    frames.push_back(f);
  }
  return frames;
}

struct PairResult {
  std::size_t matches = 0;       ///< ratio-test matches
  std::size_t with_depth = 0;    ///< of those, with a depth reading at the keypoint in A
  std::size_t consistent = 0;    ///< of those, landing within tol_px in B
  double precision = 0.0;        ///< consistent / with_depth
  double median_error_px = 0.0;  ///< over matches with depth
};

inline PairResult evaluate_rgbd_pair(cv::Feature2D& features, const RgbdFrame& a,
                                     const RgbdFrame& b, double ratio, double tol_px) {
  const Fr1Camera cam;
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  features.detectAndCompute(a.gray, cv::noArray(), ka, da);
  features.detectAndCompute(b.gray, cv::noArray(), kb, db);
  PairResult r;
  if (ka.empty() || kb.empty()) return r;
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(features.defaultNorm()).knnMatch(da, db, knn, 2);
  const Eigen::Isometry3d T_b_a = b.T_world_cam.inverse() * a.T_world_cam;
  std::vector<double> errors;
  for (const auto& m : knn) {
    if (m.size() < 2 || !(m[0].distance < ratio * m[1].distance)) continue;
    ++r.matches;
    const cv::Point2f pa = ka[static_cast<std::size_t>(m[0].queryIdx)].pt;
    const int u = static_cast<int>(std::lround(pa.x)), v = static_cast<int>(std::lround(pa.y));
    if (u < 0 || v < 0 || u >= a.depth.cols || v >= a.depth.rows) continue;
    const double z = a.depth.at<unsigned short>(v, u) / kDepthUnitsPerMetre;
    if (z <= 0.0) continue;
    ++r.with_depth;
    std::vector<cv::Point2d> distorted{cv::Point2d(pa.x, pa.y)}, normalised;
    cv::undistortPoints(distorted, normalised, cam.K, cam.distortion);
    const Eigen::Vector3d X_a(normalised[0].x * z, normalised[0].y * z, z);
    const Eigen::Vector3d X_b = T_b_a * X_a;
    if (X_b.z() <= 0.0) continue;
    std::vector<cv::Point3d> object{cv::Point3d(X_b.x(), X_b.y(), X_b.z())};
    std::vector<cv::Point2d> projected;
    cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cam.K, cam.distortion,
                      projected);
    const cv::Point2f pb = kb[static_cast<std::size_t>(m[0].trainIdx)].pt;
    const double err = std::hypot(projected[0].x - pb.x, projected[0].y - pb.y);
    errors.push_back(err);
    if (err <= tol_px) ++r.consistent;
  }
  if (r.with_depth > 0 && !errors.empty()) {
    r.precision = static_cast<double>(r.consistent) / static_cast<double>(r.with_depth);
    std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() / 2),
                     errors.end());
    r.median_error_px = errors[errors.size() / 2];
  }
  return r;
}

}  // namespace rgbdquad::surf::testing
