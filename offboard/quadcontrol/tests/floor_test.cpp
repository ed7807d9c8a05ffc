// Floor plane RANSAC, floor-aligned frame, floor map and PLY export on synthetic scenes (seeded).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "map/floor_map.hpp"
#include "map/floor_plane.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// Scene in a floor frame (z up), camera at height h pitched down by `pitch_deg`, looking along +x.
struct Scene {
  double height_m;
  double pitch_deg;
  Eigen::Isometry3d T_floor_cam() const {
    // Camera axes in the floor frame: z_cam forward-down, x_cam = -y_floor (right), y_cam =
    // down-ish.
    const double a = pitch_deg * kDegToRad;
    const Eigen::Vector3d z_cam(std::cos(a), 0.0, -std::sin(a));
    const Eigen::Vector3d x_cam(0.0, -1.0, 0.0);
    const Eigen::Vector3d y_cam = z_cam.cross(x_cam);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = x_cam;
    T.linear().col(1) = y_cam;
    T.linear().col(2) = z_cam;
    T.translation() = Eigen::Vector3d(0.0, 0.0, height_m);
    return T;
  }
};

std::vector<Eigen::Vector3d> make_points(const Scene& scene, int floor_n, int wall_n, int table_n,
                                         std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.005);
  std::vector<Eigen::Vector3d> floor_pts;
  for (int i = 0; i < floor_n; ++i)
    floor_pts.emplace_back(2.5 + 1.5 * u(rng), 1.5 * u(rng), noise(rng));
  for (int i = 0; i < wall_n; ++i)
    floor_pts.emplace_back(4.0 + noise(rng), 1.5 * u(rng), 1.0 + u(rng));
  for (int i = 0; i < table_n; ++i)
    floor_pts.emplace_back(2.0 + 0.4 * u(rng), 0.4 * u(rng), 0.75 + noise(rng));
  const Eigen::Isometry3d T_cam_floor = scene.T_floor_cam().inverse();
  std::vector<Eigen::Vector3d> cam;
  for (const auto& p : floor_pts) cam.push_back(T_cam_floor * p);
  return cam;
}

TEST(FloorPlane, FindsFloorUnderWallAndTable) {
  const Scene scenes[] = {{1.7, 30.0}, {0.5, 45.0}, {1.2, 10.0}};
  for (const auto& scene : scenes) {
    SCOPED_TRACE(scene.pitch_deg);
    const auto pts = make_points(scene, 2000, 1500, 800, 7);
    FloorPlaneOptions opt;
    const auto plane = fit_floor_plane(pts, expected_up_in_camera(scene.pitch_deg), opt);
    ASSERT_TRUE(plane.has_value());
    EXPECT_NEAR(plane->d_m, scene.height_m, 0.01);
    const Eigen::Vector3d up_true =
        scene.T_floor_cam().linear().transpose() * Eigen::Vector3d::UnitZ();
    EXPECT_GT(plane->normal_cam.dot(up_true), std::cos(1.0 * kDegToRad));
    // The floor frame puts the camera at its height and floor points at z = 0.
    const Eigen::Isometry3d T = floor_frame_from_plane(*plane);
    EXPECT_NEAR((T * Eigen::Vector3d::Zero()).z(), scene.height_m, 0.01);
    for (int i = 0; i < 50; ++i) EXPECT_NEAR((T * pts[i]).z(), 0.0, 0.03);
    // x axis = optical axis projected on the floor: a point straight ahead has y ~ 0, x > 0.
    const Eigen::Vector3d ahead = T * Eigen::Vector3d(0.0, 0.0, 1.0);
    EXPECT_GT(ahead.x(), 0.0);
    EXPECT_NEAR(ahead.y(), 0.0, 0.02);
  }
}

TEST(FloorPlane, WallAloneIsNotAFloor) {
  const Scene scene{1.7, 30.0};
  const auto pts = make_points(scene, 0, 2000, 0, 3);
  EXPECT_FALSE(fit_floor_plane(pts, expected_up_in_camera(scene.pitch_deg), FloorPlaneOptions{})
                   .has_value());
}

TEST(FloorPlane, DeterministicForASeed) {
  const Scene scene{1.7, 30.0};
  const auto pts = make_points(scene, 500, 500, 200, 11);
  const auto a = fit_floor_plane(pts, expected_up_in_camera(30.0), FloorPlaneOptions{});
  const auto b = fit_floor_plane(pts, expected_up_in_camera(30.0), FloorPlaneOptions{});
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->inliers, b->inliers);
  EXPECT_DOUBLE_EQ(a->d_m, b->d_m);
}

TEST(FloorPlane, BadInputGivesNoPlane) {
  std::vector<Eigen::Vector3d> two{{0, 0, 1}, {1, 0, 1}};
  EXPECT_FALSE(fit_floor_plane(two, Eigen::Vector3d(0, -1, 0), FloorPlaneOptions{}));
  const auto pts = make_points({1.7, 30.0}, 500, 0, 0, 5);
  EXPECT_FALSE(fit_floor_plane(pts, Eigen::Vector3d(0, 0, 0), FloorPlaneOptions{}));
  FloorPlaneOptions bad;
  bad.iterations = 0;
  EXPECT_FALSE(fit_floor_plane(pts, Eigen::Vector3d(0, -1, 0), bad));
}

TEST(FloorMap, ClassifiesCellsAndRendersNorthUp) {
  FloorMapOptions opt;
  opt.size_m = 2.0;
  opt.resolution_m = 0.5;  // 4x4 cells, origin (-1, -1)
  FloorMap map(opt);
  ASSERT_EQ(map.width_cells(), 4);
  std::vector<ColouredPoint> pts = {
      {Eigen::Vector3f(-0.9f, -0.9f, 0.01f), 10, 20, 30},  // floor, cell (0,0)
      {Eigen::Vector3f(0.6f, 0.6f, 1.0f), 200, 0, 0},      // obstacle, cell (3,3)
      {Eigen::Vector3f(0.1f, 0.1f, 3.0f), 1, 1, 1},        // above obstacle band: cloud only
      {Eigen::Vector3f(9.0f, 9.0f, 0.0f), 1, 1, 1},        // outside the grid: cloud only
      {Eigen::Vector3f(NAN, 0.0f, 0.0f), 1, 1, 1},         // skipped
  };
  map.add_points(pts);
  EXPECT_EQ(map.floor_counts()[0], 1);
  EXPECT_EQ(map.obstacle_counts()[15], 1);
  EXPECT_EQ(map.cloud().size(), 4u);
  const auto img = map.render_rgb();
  ASSERT_EQ(img.size(), 4u * 4u * 3u);
  // cell (row 0, col 0) = smallest y -> bottom-left pixel (image row 3)
  EXPECT_GT(img[(3 * 4 + 0) * 3], 100);
  // cell (3,3) obstacle -> top-right pixel (image row 0), red
  EXPECT_EQ(img[(0 * 4 + 3) * 3 + 0], 170);
  EXPECT_EQ(img[(0 * 4 + 3) * 3 + 1], 40);
  // Same voxel twice keeps one cloud point.
  map.add_points({pts[0]});
  EXPECT_EQ(map.cloud().size(), 4u);
  EXPECT_EQ(map.floor_counts()[0], 2);
}

TEST(FloorMap, PlyHeaderMatchesVertexCount) {
  FloorMap map(FloorMapOptions{});
  map.add_points(
      {{Eigen::Vector3f(0.0f, 0.0f, 0.0f), 1, 2, 3}, {Eigen::Vector3f(1.0f, 0.0f, 0.0f), 4, 5, 6}});
  const std::string ply = map.to_ply();
  EXPECT_EQ(ply.rfind("ply\nformat ascii 1.0\n", 0), 0u);
  EXPECT_NE(ply.find("element vertex 2\n"), std::string::npos);
  EXPECT_NE(ply.find("1 0 0 4 5 6\n"), std::string::npos);
}

TEST(FloorMap, InvalidOptionsThrow) {
  FloorMapOptions opt;
  opt.resolution_m = 0.001;  // 10000 cells per side > protocol limit
  EXPECT_THROW(FloorMap{opt}, std::invalid_argument);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
