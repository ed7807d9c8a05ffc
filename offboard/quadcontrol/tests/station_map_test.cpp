// The ground station's dashboard caches that need OpenCV, without sockets or threads: the newest
// frame's images (FrameImages: encoded once per frame, dropped on a new one) and the map
// (StationMap: depth sub-sampling, colouring, revision, cloud sub-sampling). GIVEN/WHEN/THEN.
#include "app/station_map.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "app/frame_images.hpp"

namespace rgbdquad::quadcontrol {
namespace {

constexpr int kWidthPx = 64, kHeightPx = 48;

/// A frame of uniform colour (BGR) with every depth pixel at `depth_m` (0: no reading).
CameraFrame uniform_frame(std::int64_t sequence, cv::Vec3b bgr, double depth_m) {
  CameraFrame f;
  f.sequence = sequence;
  f.rgb = cv::Mat(kHeightPx, kWidthPx, CV_8UC3, cv::Scalar(bgr[0], bgr[1], bgr[2]));
  f.intrinsics.fx_px = f.intrinsics.fy_px = 50.0;
  f.intrinsics.cx_px = kWidthPx / 2.0;
  f.intrinsics.cy_px = kHeightPx / 2.0;
  const auto units = static_cast<std::uint16_t>(depth_m * f.intrinsics.depth_units_per_m);
  f.depth = cv::Mat(kHeightPx, kWidthPx, CV_16UC1, cv::Scalar(units));
  return f;
}

TEST(FrameImages, GivenNoFrameWhenImagesAreAskedThenThereAreNone) {
  FrameImages images;
  EXPECT_EQ(images.sequence(), -1);
  EXPECT_FALSE(images.rgb_jpeg());
  EXPECT_FALSE(images.depth_png());
}

TEST(FrameImages, GivenAFrameWhenEncodedThenTheJpegAndPngDecodeToItsSize) {
  FrameImages images;
  images.set_frame(uniform_frame(7, {10, 20, 200}, 1.0));
  EXPECT_EQ(images.sequence(), 7);
  const auto jpg = images.rgb_jpeg();
  const auto png = images.depth_png();
  ASSERT_TRUE(jpg && png);
  const cv::Mat rgb =
      cv::imdecode(std::vector<std::uint8_t>(jpg->begin(), jpg->end()), cv::IMREAD_UNCHANGED);
  const cv::Mat grey =
      cv::imdecode(std::vector<std::uint8_t>(png->begin(), png->end()), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(rgb.cols, kWidthPx);
  EXPECT_EQ(grey.type(), CV_8UC1);
  // 1 m of the 5 m display range: 255 - 235 * 0.2 = 208.
  EXPECT_EQ(grey.at<std::uint8_t>(0, 0), 208);
}

TEST(FrameImages, GivenNoDepthReadingWhenEncodedThenThePixelIsBlack) {
  FrameImages images;
  images.set_frame(uniform_frame(1, {0, 0, 0}, 0.0));
  const auto png = images.depth_png();
  ASSERT_TRUE(png);
  const cv::Mat grey =
      cv::imdecode(std::vector<std::uint8_t>(png->begin(), png->end()), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(grey.at<std::uint8_t>(5, 5), 0);
}

TEST(FrameImages, GivenEncodedImagesWhenANewFrameArrivesThenTheyAreEncodedAgain) {
  FrameImages images;
  images.set_frame(uniform_frame(1, {0, 0, 0}, 1.0));
  const auto first = images.depth_png();
  EXPECT_EQ(images.depth_png(), first);  // same frame: the cached bytes
  images.set_frame(uniform_frame(2, {0, 0, 0}, 4.0));
  const auto second = images.depth_png();
  ASSERT_TRUE(first && second);
  EXPECT_NE(*first, *second);
}

TEST(StationMap, GivenADepthImageWhenSubSampledThenEveryStepthPixelWithinRangeIsKept) {
  const CameraFrame f = uniform_frame(1, {0, 0, 0}, 2.0);
  EXPECT_EQ(camera_points(f, 4, 4.0).size(), std::size_t{(kWidthPx / 4) * (kHeightPx / 4)});
  EXPECT_TRUE(camera_points(f, 4, 1.5).empty());  // beyond max depth
  const auto pts = camera_points(f, 8, 4.0);
  ASSERT_FALSE(pts.empty());
  EXPECT_DOUBLE_EQ(pts.front().z(), 2.0);
  EXPECT_DOUBLE_EQ(pts.front().x(), (0 - kWidthPx / 2.0) * 2.0 / 50.0);
  CameraFrame not_depth = f;
  not_depth.depth = cv::Mat(kHeightPx, kWidthPx, CV_8UC1, cv::Scalar(1));
  EXPECT_TRUE(camera_points(not_depth, 4, 4.0).empty());
}

TEST(StationMap, GivenPointsInsideAndOutsideTheImageWhenColouredThenOutsideOnesAreGrey) {
  const CameraFrame f = uniform_frame(1, {10, 20, 200}, 1.0);
  const std::vector<Eigen::Vector3d> cam = {{0.0, 0.0, 1.0}, {10.0, 0.0, 1.0}};
  const auto pts = coloured_floor_points(f, cam, Eigen::Isometry3d::Identity());
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_EQ(pts[0].r, 200);  // BGR pixel -> r, g, b
  EXPECT_EQ(pts[0].g, 20);
  EXPECT_EQ(pts[0].b, 10);
  EXPECT_EQ(pts[1].r, 128);  // projects outside the image
}

TEST(StationMap, GivenFramesWhenAddedThenTheRevisionCountsThemAndTheCloudIsSubSampled) {
  StationMap map(FloorMapOptions{});
  EXPECT_EQ(map.revision(), 0);
  const CameraFrame f = uniform_frame(1, {0, 0, 255}, 1.0);
  Eigen::Isometry3d T_floor_cam = Eigen::Isometry3d::Identity();
  T_floor_cam.translation() = Eigen::Vector3d(0.0, 0.0, 1.0);
  map.add_frame(f, camera_points(f, 2, 4.0), T_floor_cam);
  map.add_frame(f, {}, T_floor_cam);
  EXPECT_EQ(map.revision(), 2);
  const std::size_t total = map.map().cloud().size();
  ASSERT_GT(total, 10u);
  const nlohmann::json all = map.cloud_json(total, std::nullopt);
  EXPECT_EQ(all["points"].size(), total);
  EXPECT_TRUE(all["pose"].is_null());
  const nlohmann::json few = map.cloud_json(10, CraftPose{1.0, 2.0, 3.0, 90.0});
  EXPECT_LE(few["points"].size(), 10u);
  EXPECT_EQ(few["total"], total);
  EXPECT_EQ(few["pose"]["yaw_deg"], 90.0);
}

TEST(StationMap, GivenAMapWhenRenderedThenThePngDecodesToTheMapSize) {
  const StationMap map(FloorMapOptions{});
  const std::string png = map.png();
  const cv::Mat img =
      cv::imdecode(std::vector<std::uint8_t>(png.begin(), png.end()), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(img.cols, map.map().width_cells());
  EXPECT_EQ(img.type(), CV_8UC3);
  EXPECT_EQ(map.ply().rfind("ply", 0), 0u);
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
