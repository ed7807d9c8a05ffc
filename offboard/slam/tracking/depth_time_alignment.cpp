// Depth re-timed to the colour image; see depth_time_alignment.hpp.
#include "slam/tracking/depth_time_alignment.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>

namespace rgbdquad::slam {

cv::Mat align_depth_to_colour_time(const cv::Mat& depth, const Intrinsics& k,
                                   const Eigen::Vector3d& omega_cam_rad_per_s,
                                   double colour_minus_depth_s) {
  const Eigen::Vector3d rotvec = omega_cam_rad_per_s * colour_minus_depth_s;
  const double angle = rotvec.norm();
  // Below 0.01 px of motion at the image edge the warp changes nothing.
  const double edge_px = angle * (k.fx_px + depth.cols / 2.0);
  if (depth.empty() || depth.type() != CV_16UC1 || !std::isfinite(angle) || edge_px < 0.01)
    return depth;
  // R_d_c: the colour camera's axes in the depth camera's frame (the camera rotated by `rotvec`
  // from depth time to colour time: R_depth_colour = exp(rotvec)).
  const Eigen::Matrix3d R_d_c = Eigen::AngleAxisd(angle, rotvec / angle).toRotationMatrix();
  const Eigen::Matrix3d R_c_d = R_d_c.transpose();
  cv::Mat out(depth.size(), CV_16UC1, cv::Scalar(0));
  const double ifx = 1.0 / k.fx_px, ify = 1.0 / k.fy_px;
  // The ray is linear in u along a row: start at u = 0 and step by the rotated x axis.
  const Eigen::Vector3d step_u = R_d_c.col(0) * ifx;
  const Eigen::Vector3d r_c_z = R_c_d.row(2).transpose();
  for (int v = 0; v < depth.rows; ++v) {
    auto* row = out.ptr<std::uint16_t>(v);
    // The colour pixel's ray at colour time, in the depth camera's frame.
    Eigen::Vector3d ray_d = R_d_c * Eigen::Vector3d(-k.cx_px * ifx, (v - k.cy_px) * ify, 1.0);
    for (int u = 0; u < depth.cols; ++u, ray_d += step_u) {
      if (ray_d.z() <= 0) continue;
      const double xd = ray_d.x() / ray_d.z(), yd = ray_d.y() / ray_d.z();
      const int ui = static_cast<int>(std::lround(k.fx_px * xd + k.cx_px));
      const int vi = static_cast<int>(std::lround(k.fy_px * yd + k.cy_px));
      if (ui < 0 || vi < 0 || ui >= depth.cols || vi >= depth.rows) continue;
      const std::uint16_t zd = depth.at<std::uint16_t>(vi, ui);
      if (zd == 0) continue;
      // The point at depth zd along the depth camera's ray (xd, yd, 1), seen from the colour
      // camera: its z there.
      const double zc = zd * r_c_z.dot(Eigen::Vector3d(xd, yd, 1.0));
      if (zc > 0 && zc < 65535.0) row[u] = static_cast<std::uint16_t>(std::lround(zc));
    }
  }
  return out;
}

}  // namespace rgbdquad::slam
