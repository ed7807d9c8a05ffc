// PLY map and text writers.
#include "slam/pipeline/map_export.hpp"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

#include "slam/features/features.hpp"

namespace rgbdquad::slam {

namespace {
void put_f32(std::vector<char>* buf, float v) {
  std::uint32_t u;
  std::memcpy(&u, &v, 4);
  for (int i = 0; i < 4; ++i) buf->push_back(static_cast<char>((u >> (8 * i)) & 0xFF));
}

void put_point(std::vector<char>* buf, const Eigen::Vector3d& p, const cv::Vec3b& bgr) {
  put_f32(buf, static_cast<float>(p.x()));
  put_f32(buf, static_cast<float>(p.y()));
  put_f32(buf, static_cast<float>(p.z()));
  buf->push_back(static_cast<char>(bgr[2]));
  buf->push_back(static_cast<char>(bgr[1]));
  buf->push_back(static_cast<char>(bgr[0]));
}

/// Binary little-endian PLY with x y z (float) and red green blue (uchar) per vertex.
long write_ply(const std::string& path, const std::vector<char>& body, long count,
               const std::string& comment, std::string* error) {
  std::ofstream out(path, std::ios::binary);
  if (!out) {
    if (error) *error = "cannot write '" + path + "'";
    return -1;
  }
  out << "ply\nformat binary_little_endian 1.0\ncomment " << comment << "\n"
      << "element vertex " << count << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  if (!out) {
    if (error) *error = "write failed for '" + path + "'";
    return -1;
  }
  return count;
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
        put_point(&body, p, rgb.at<cv::Vec3b>(v, u));
        ++count;
      }
    }
  }
  return write_ply(path, body, count, "RGB-D SLAM keyframe map (world frame, m)", error);
}

long write_map_points_ply(const std::string& path, SharedMap& shared, std::string* error) {
  std::vector<char> body;
  long count = 0;
  {
    std::lock_guard<MapMutex> lock(shared.mutex);
    for (const auto& [id, p] : shared.map.points()) {
      cv::Vec3b c(128, 128, 128);
      for (const auto& [kf_id, kp] : p.observations) {
        const MapKeyframe* kf = shared.map.keyframe(kf_id);
        if (kf && static_cast<std::size_t>(kp) < kf->features.features->colours_bgr.size()) {
          c = kf->features.features->colours_bgr[static_cast<std::size_t>(kp)];
          break;
        }
      }
      put_point(&body, p.p_world_m, c);
      ++count;
    }
  }
  return write_ply(path, body, count, "RGB-D SLAM local-map points (world frame, m)", error);
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

}  // namespace rgbdquad::slam
