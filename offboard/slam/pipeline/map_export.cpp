// PLY map and text writers.
#include "slam/pipeline/map_export.hpp"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

#include "slam/features/features.hpp"

namespace slam {

namespace {
void put_f32(std::vector<char>* buf, float v) {
  std::uint32_t u;
  std::memcpy(&u, &v, 4);
  for (int i = 0; i < 4; ++i) buf->push_back(static_cast<char>((u >> (8 * i)) & 0xFF));
}
}  // namespace

long write_keyframe_map_ply(const std::string& path, const BackEnd& backend, const Intrinsics& k,
                            const MapExportOptions& o, std::string* error) {
  std::vector<char> body;
  long count = 0;
  const int stride = std::max(1, o.pixel_stride);
  for (const auto& [id, kf] : backend.keyframes()) {
    const Eigen::Isometry3d T = backend.keyframe_pose(id);
    const cv::Mat& depth = kf.frame.depth;
    const cv::Mat& rgb = kf.frame.rgb;
    if (depth.empty() || depth.type() != CV_16UC1 || rgb.type() != CV_8UC3) continue;
    for (int v = 0; v < depth.rows; v += stride) {
      for (int u = 0; u < depth.cols; u += stride) {
        const std::uint16_t raw = depth.at<std::uint16_t>(v, u);
        if (raw == 0) continue;
        const double z = raw / k.depth_units_per_m;
        if (z > o.max_depth_m) continue;
        const Eigen::Vector3d p = T * back_project(k, u, v, z);
        const cv::Vec3b c = rgb.at<cv::Vec3b>(v, u);
        put_f32(&body, static_cast<float>(p.x()));
        put_f32(&body, static_cast<float>(p.y()));
        put_f32(&body, static_cast<float>(p.z()));
        body.push_back(static_cast<char>(c[2]));
        body.push_back(static_cast<char>(c[1]));
        body.push_back(static_cast<char>(c[0]));
        ++count;
      }
    }
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) {
    if (error) *error = "cannot write '" + path + "'";
    return -1;
  }
  out << "ply\nformat binary_little_endian 1.0\ncomment RGB-D SLAM keyframe map (world frame, m)\n"
      << "element vertex " << count << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  if (!out) {
    if (error) *error = "write failed for '" + path + "'";
    return -1;
  }
  return count;
}

bool write_text_file(const std::string& path, const std::string& text, std::string* error) {
  std::ofstream out(path);
  out << text;
  if (!out) {
    if (error) *error = "cannot write '" + path + "'";
    return false;
  }
  return true;
}

}  // namespace slam
