// The 2D top-down floor map and the coloured point-cloud map (thesis Section 3.3.3: a sub-sampled
// set of floor points, accumulated with the egomotion, makes the 2D map).
//
// Points arrive in the floor-aligned world frame (z = height above the floor). A point within
// floor_band_m of z = 0 marks its cell as floor; a point between obstacle_min_height_m and
// obstacle_max_height_m marks it as an obstacle. Counts saturate at 255 (the protocol's
// POINT_COUNT_U8 cell format). The cloud keeps one coloured point per voxel, up to
// max_cloud_points. Grid: cell (row, col) covers x in [origin_x + col*res, +res), y in [origin_y +
// row*res, +res). Not thread-safe: the app guards the instance with a mutex.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

namespace rgbdquad::quadcontrol {

struct FloorMapOptions {
  double resolution_m = 0.05;             ///< 5 cm cells: finer than the craft's ~0.5 m span
  double size_m = 10.0;                   ///< 10 m x 10 m around the take-off point: a large room
  double floor_band_m = 0.05;             ///< 2.5x the floor-plane RANSAC inlier distance
  double obstacle_min_height_m = 0.15;    ///< above floor noise and carpet
  double obstacle_max_height_m = 2.2;     ///< below a typical ceiling
  double voxel_m = 0.03;                  ///< cloud sub-sampling: one point per 3 cm voxel
  std::size_t max_cloud_points = 200000;  ///< ~5 MB of points: bounded memory for long flights
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

struct ColouredPoint {
  Eigen::Vector3f p_world;
  std::uint8_t r = 0, g = 0, b = 0;
};

class FloorMap {
 public:
  explicit FloorMap(FloorMapOptions options);

  /// Adds points (world frame, metres) with colours; non-finite points are skipped.
  void add_points(const std::vector<ColouredPoint>& points_world);

  int width_cells() const { return cells_per_side_; }
  int height_cells() const { return cells_per_side_; }
  double resolution_m() const { return options_.resolution_m; }
  double origin_x_m() const { return -options_.size_m / 2.0; }
  double origin_y_m() const { return -options_.size_m / 2.0; }
  const std::vector<std::uint8_t>& floor_counts() const { return floor_counts_; }
  const std::vector<std::uint8_t>& obstacle_counts() const { return obstacle_counts_; }
  const std::vector<ColouredPoint>& cloud() const { return cloud_; }

  /// RGB8 image, row 0 = max y (north up, as seen from above): unknown dark grey, floor light
  /// grey (brighter with more points), obstacles dark red.
  std::vector<std::uint8_t> render_rgb() const;

  /// ASCII PLY of the coloured cloud (x y z in metres, red green blue uchar).
  std::string to_ply() const;

 private:
  FloorMapOptions options_;
  int cells_per_side_;
  std::vector<std::uint8_t> floor_counts_;
  std::vector<std::uint8_t> obstacle_counts_;
  std::vector<ColouredPoint> cloud_;
  std::unordered_map<std::int64_t, std::size_t> voxels_;
};

}  // namespace rgbdquad::quadcontrol
