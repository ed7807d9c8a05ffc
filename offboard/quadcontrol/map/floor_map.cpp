// Floor map and point-cloud accumulation: see floor_map.hpp.
#include "map/floor_map.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {
constexpr int kMaxCellsPerSide = 4096;             // protocol limit max_map_dimension_cells
constexpr std::int64_t kVoxelAxisRange = 1 << 20;  // +-2^19 voxels per axis fit the key

void bump(std::uint8_t& c) {
  if (c < 255) ++c;
}
}  // namespace

bool FloorMapOptions::is_valid(std::string* error) const {
  if (!(resolution_m > 0.0) || !(size_m > 0.0))
    return reject(error, "map: resolution_m and size_m must be > 0");
  if (size_m / resolution_m > kMaxCellsPerSide)
    return reject(error, "map: more than 4096 cells per side");
  if (!(floor_band_m > 0.0) || !(voxel_m > 0.0))
    return reject(error, "map: floor_band_m and voxel_m must be > 0");
  if (!(obstacle_min_height_m > floor_band_m && obstacle_max_height_m > obstacle_min_height_m)) {
    return reject(error, "map: need floor_band_m < obstacle_min_height_m < obstacle_max_height_m");
  }
  return true;
}

FloorMap::FloorMap(FloorMapOptions options) : options_(options) {
  if (std::string error; !options_.is_valid(&error)) throw std::invalid_argument(error);
  cells_per_side_ = static_cast<int>(std::lround(options_.size_m / options_.resolution_m));
  floor_counts_.assign(static_cast<std::size_t>(cells_per_side_) * cells_per_side_, 0);
  obstacle_counts_ = floor_counts_;
}

void FloorMap::add_points(const std::vector<ColouredPoint>& points) {
  for (const auto& pt : points) {
    if (!pt.p_world.allFinite()) continue;
    const double x = pt.p_world.x(), y = pt.p_world.y(), z = pt.p_world.z();
    const int col = static_cast<int>(std::floor((x - origin_x_m()) / options_.resolution_m));
    const int row = static_cast<int>(std::floor((y - origin_y_m()) / options_.resolution_m));
    if (col >= 0 && row >= 0 && col < cells_per_side_ && row < cells_per_side_) {
      const std::size_t idx = static_cast<std::size_t>(row) * cells_per_side_ + col;
      if (std::abs(z) <= options_.floor_band_m)
        bump(floor_counts_[idx]);
      else if (z >= options_.obstacle_min_height_m && z <= options_.obstacle_max_height_m)
        bump(obstacle_counts_[idx]);
    }
    if (cloud_.size() >= options_.max_cloud_points) continue;
    const auto vx = static_cast<std::int64_t>(std::floor(x / options_.voxel_m));
    const auto vy = static_cast<std::int64_t>(std::floor(y / options_.voxel_m));
    const auto vz = static_cast<std::int64_t>(std::floor(z / options_.voxel_m));
    const std::int64_t half = kVoxelAxisRange / 2;
    if (std::abs(vx) >= half || std::abs(vy) >= half || std::abs(vz) >= half) continue;
    const std::int64_t key =
        ((vx + half) * kVoxelAxisRange + (vy + half)) * kVoxelAxisRange + (vz + half);
    if (voxels_.emplace(key, cloud_.size()).second) cloud_.push_back(pt);
  }
}

std::vector<std::uint8_t> FloorMap::render_rgb() const {
  const int n = cells_per_side_;
  std::vector<std::uint8_t> img(static_cast<std::size_t>(n) * n * 3);
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      const std::size_t cell = static_cast<std::size_t>(row) * n + col;
      // Image row 0 is the top = largest y (north up).
      std::uint8_t* px = &img[(static_cast<std::size_t>(n - 1 - row) * n + col) * 3];
      if (obstacle_counts_[cell] > 0) {
        px[0] = 170;
        px[1] = 40;
        px[2] = 40;
      } else if (floor_counts_[cell] > 0) {
        const int v = std::min(250, 150 + 10 * floor_counts_[cell]);
        px[0] = px[1] = px[2] = static_cast<std::uint8_t>(v);
      } else {
        px[0] = px[1] = px[2] = 40;
      }
    }
  }
  return img;
}

std::string FloorMap::to_ply() const {
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\ncomment quad-control point-cloud map, floor-aligned world frame, "
         "metres\n"
      << "element vertex " << cloud_.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  for (const auto& p : cloud_) {
    out << p.p_world.x() << ' ' << p.p_world.y() << ' ' << p.p_world.z() << ' ' << int(p.r) << ' '
        << int(p.g) << ' ' << int(p.b) << '\n';
  }
  return out.str();
}

}  // namespace rgbdquad::quadcontrol
