// Synthetic scenes for the local-map SLAM's unit tests: poses, points in front of a camera,
// ORB-like random descriptors, and frames whose keypoints are those points' exact projections.
#pragma once

#include <cmath>
#include <memory>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "slam/features/features.hpp"
#include "slam/map/map.hpp"

namespace rgbdquad::slam::synthetic {

inline CameraModel fr1_camera() { return CameraModel::from(Intrinsics{}); }

inline Eigen::Isometry3d pose(double rx, double ry, double rz, double tx, double ty, double tz) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(tx, ty, tz);
  return T;
}

/// Points spread in front of the world camera, 1-3 m deep.
inline std::vector<Eigen::Vector3d> scene(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> xy(-1.0, 1.0), z(1.0, 3.0);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(xy(rng), 0.75 * xy(rng), z(rng));
  return pts;
}

struct SyntheticFrame {
  std::shared_ptr<FrameFeatures> features = std::make_shared<FrameFeatures>();
  TrackedFeatures tracked;
};

inline cv::Mat random_descriptors(int n, std::uint32_t seed) {
  cv::Mat d(n, 32, CV_8U);
  cv::RNG rng(seed);
  rng.fill(d, cv::RNG::UNIFORM, 0, 256);
  return d;
}

inline SyntheticFrame make_frame(const std::vector<Eigen::Vector3d>& pts,
                                 const Eigen::Isometry3d& T_cam_world, const cv::Mat& desc,
                                 const CameraModel& cam) {
  SyntheticFrame f;
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  std::vector<int> rows;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3d pc = T_cam_world * pts[i];
    const Eigen::Vector3d uvd = cam.project(pc);
    if (pc.z() <= 0 || !cam.in_image(uvd.x(), uvd.y())) continue;
    f.features->keypoints.emplace_back(
        cv::Point2f(static_cast<float>(uvd.x()), static_cast<float>(uvd.y())),
        static_cast<float>(fo.orb_patch_size));
    f.features->points_cam_m.push_back(pc);
    f.features->colours_bgr.emplace_back(0, 0, 0);
    rows.push_back(static_cast<int>(i));
  }
  f.features->descriptors.create(static_cast<int>(rows.size()), desc.cols, desc.type());
  for (std::size_t r = 0; r < rows.size(); ++r)
    desc.row(rows[r]).copyTo(f.features->descriptors.row(static_cast<int>(r)));
  f.tracked = TrackedFeatures::from(f.features, cam, fo);
  return f;
}

/// The frame's keypoints as a camera without depth sees them (FrameFeatures::depthless): their
/// points become bearings at z = 1.
inline void drop_depth(SyntheticFrame* f, const CameraModel& cam) {
  for (Eigen::Vector3d& p : f->features->points_cam_m) p /= p.z();
  FeatureOptions fo;
  fo.kind = DetectorKind::kOrb;
  f->tracked = TrackedFeatures::from(f->features, cam, fo);
}

}  // namespace rgbdquad::slam::synthetic
