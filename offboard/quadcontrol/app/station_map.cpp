// The ground station's map: see station_map.hpp.
#include "app/station_map.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rgbdquad::quadcontrol {

std::vector<Eigen::Vector3d> camera_points(const CameraFrame& f, int step, double max_depth_m) {
  std::vector<Eigen::Vector3d> pts;
  if (f.depth.type() != CV_16UC1) return pts;
  const auto& k = f.intrinsics;
  for (int v = 0; v < f.depth.rows; v += step) {
    const auto* row = f.depth.ptr<std::uint16_t>(v);
    for (int u = 0; u < f.depth.cols; u += step) {
      if (row[u] == 0) continue;
      const double z = row[u] / k.depth_units_per_m;
      if (z > max_depth_m) continue;
      pts.emplace_back((u - k.cx_px) * z / k.fx_px, (v - k.cy_px) * z / k.fy_px, z);
    }
  }
  return pts;
}

std::vector<ColouredPoint> coloured_floor_points(const CameraFrame& frame,
                                                 const std::vector<Eigen::Vector3d>& cam_points,
                                                 const Eigen::Isometry3d& T_floor_cam) {
  std::vector<ColouredPoint> world;
  world.reserve(cam_points.size());
  const auto& k = frame.intrinsics;
  for (const auto& p : cam_points) {
    const Eigen::Vector3d w = T_floor_cam * p;
    const int u = static_cast<int>(std::lround(p.x() * k.fx_px / p.z() + k.cx_px));
    const int v = static_cast<int>(std::lround(p.y() * k.fy_px / p.z() + k.cy_px));
    ColouredPoint cp{w.cast<float>(), 128, 128, 128};
    if (u >= 0 && v >= 0 && u < frame.rgb.cols && v < frame.rgb.rows &&
        frame.rgb.type() == CV_8UC3) {
      const auto& bgr = frame.rgb.at<cv::Vec3b>(v, u);
      cp.r = bgr[2];
      cp.g = bgr[1];
      cp.b = bgr[0];
    }
    world.push_back(cp);
  }
  return world;
}

nlohmann::json pose_json(const CraftPose& p) {
  return {{"x_m", p.x_m}, {"y_m", p.y_m}, {"z_m", p.z_m}, {"yaw_deg", p.yaw_deg}};
}

void StationMap::add_frame(const CameraFrame& frame, const std::vector<Eigen::Vector3d>& cam_points,
                           const Eigen::Isometry3d& T_floor_cam) {
  map_.add_points(coloured_floor_points(frame, cam_points, T_floor_cam));
  ++revision_;
}

std::string StationMap::png_of_render(std::vector<std::uint8_t> rgb, int cells) {
  cv::Mat img(cells, cells, CV_8UC3, rgb.data());
  cv::Mat bgr;
  cv::cvtColor(img, bgr, cv::COLOR_RGB2BGR);
  std::vector<std::uint8_t> buf;
  cv::imencode(".png", bgr, buf);
  return std::string(buf.begin(), buf.end());
}

nlohmann::json StationMap::cloud_json(std::size_t max_points,
                                      const std::optional<CraftPose>& pose) const {
  const auto& cloud = map_.cloud();
  nlohmann::json pts = nlohmann::json::array();
  const std::size_t stride = std::max<std::size_t>(
      1, (cloud.size() + max_points - 1) / std::max<std::size_t>(1, max_points));
  for (std::size_t i = 0; i < cloud.size(); i += stride) {
    const auto& p = cloud[i];
    pts.push_back({std::round(p.p_world.x() * 1000) / 1000, std::round(p.p_world.y() * 1000) / 1000,
                   std::round(p.p_world.z() * 1000) / 1000, p.r, p.g, p.b});
  }
  return {{"points", pts},
          {"total", cloud.size()},
          {"pose", pose ? pose_json(*pose) : nlohmann::json(nullptr)}};
}

}  // namespace rgbdquad::quadcontrol
