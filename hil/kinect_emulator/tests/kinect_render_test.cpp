// GoogleTest of the C++ Kinect renderer's geometry and contract on a synthetic one-texture room.
// The bit-for-bit comparison with the numpy renderer is tests/test_native.py (pytest).
#include "kinect_render.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace {

constexpr int kW = 64;
constexpr int kH = 48;
constexpr double kF = 50.0;

struct Scene {
  std::vector<uint32_t> tex = std::vector<uint32_t>(2 * 20 * 20, 0x00804020u);
  double lo[3] = {-4.0, -3.0, 0.0};
  double hi[3] = {4.0, 3.0, 3.0};
  KrRenderer* make(int n_obstacles, const double* boxes) const {
    return kr_create(kW, kH, kF, kF, (kW - 1) / 2.0, (kH - 1) / 2.0, lo, hi, n_obstacles, boxes,
                     1.2, 0.9, tex.data(), 2, 20, 20);
  }
};

// Camera at (0, 0, 1.5) looking along room +x: camera x = room -y, camera y = room -z.
const double kLookPlusX[16] = {0, 0, 1, 0.0, -1, 0, 0, 0.0, 0, -1, 0, 1.5, 0, 0, 0, 1};

KrSensor ideal_sensor() {
  KrSensor s{};
  s.min_range_m = 0.5;
  s.max_range_m = 4.5;
  return s;  // no shadows, no quantisation, no noise, no dropouts
}

TEST(KinectRender, GivenAWallFourMetresAhead_WhenRendered_ThenCentreDepthIs4000mm) {
  Scene scene;
  KrRenderer* r = scene.make(0, nullptr);
  ASSERT_NE(r, nullptr);
  std::vector<uint8_t> rgb(kW * kH * 3);
  std::vector<uint16_t> depth(kW * kH);
  KrSensor s = ideal_sensor();
  ASSERT_EQ(kr_render(r, kLookPlusX, nullptr, &s, rgb.data(), depth.data()), 0);
  EXPECT_EQ(depth[(kH / 2) * kW + kW / 2], 4000);
  // The texel R | G << 8 | B << 16 comes out as R, G, B bytes.
  EXPECT_EQ(rgb[3 * ((kH / 2) * kW + kW / 2)], 0x20);
  EXPECT_EQ(rgb[3 * ((kH / 2) * kW + kW / 2) + 2], 0x80);
  kr_destroy(r);
}

TEST(KinectRender, GivenABoxInFront_WhenRendered_ThenItOccludesTheWall) {
  Scene scene;
  const double box[6] = {2.0, -0.5, 0.0, 2.5, 0.5, 3.0};
  KrRenderer* r = scene.make(1, box);
  ASSERT_NE(r, nullptr);
  const int32_t whole_image[4] = {0, kH, 0, kW};
  std::vector<uint8_t> rgb(kW * kH * 3);
  std::vector<uint16_t> depth(kW * kH);
  KrSensor s = ideal_sensor();
  ASSERT_EQ(kr_render(r, kLookPlusX, whole_image, &s, rgb.data(), depth.data()), 0);
  EXPECT_EQ(depth[(kH / 2) * kW + kW / 2], 2000);
  // The same box outside its screen rectangle is not tested: the wall shows.
  const int32_t empty_rect[4] = {0, 0, 0, 0};
  ASSERT_EQ(kr_render(r, kLookPlusX, empty_rect, &s, rgb.data(), depth.data()), 0);
  EXPECT_EQ(depth[(kH / 2) * kW + kW / 2], 4000);
  kr_destroy(r);
}

TEST(KinectRender, GivenAWallBeyondMaxRange_WhenRendered_ThenNoReading) {
  Scene scene;
  KrRenderer* r = scene.make(0, nullptr);
  std::vector<uint8_t> rgb(kW * kH * 3);
  std::vector<uint16_t> depth(kW * kH);
  KrSensor s = ideal_sensor();
  s.max_range_m = 3.0;
  ASSERT_EQ(kr_render(r, kLookPlusX, nullptr, &s, rgb.data(), depth.data()), 0);
  EXPECT_EQ(depth[(kH / 2) * kW + kW / 2], 0);
  kr_destroy(r);
}

TEST(KinectRender, GivenInvalidArguments_ThenRejected) {
  Scene scene;
  EXPECT_EQ(kr_create(0, kH, kF, kF, 0, 0, scene.lo, scene.hi, 0, nullptr, 1.2, 0.9,
                      scene.tex.data(), 2, 20, 20),
            nullptr);
  EXPECT_EQ(scene.make(42, nullptr), nullptr);  // face ids are uint8
  KrRenderer* r = scene.make(0, nullptr);
  std::vector<uint8_t> rgb(kW * kH * 3);
  std::vector<uint16_t> depth(kW * kH);
  KrSensor s = ideal_sensor();
  double nan_pose[16];
  for (int i = 0; i < 16; ++i) nan_pose[i] = kLookPlusX[i];
  nan_pose[3] = 0.0 / 0.0;
  EXPECT_EQ(kr_render(r, nan_pose, nullptr, &s, rgb.data(), depth.data()), -1);
  EXPECT_EQ(kr_render(r, kLookPlusX, nullptr, nullptr, rgb.data(), depth.data()), -1);
  EXPECT_EQ(kr_api_version(), KR_API_VERSION);
  kr_destroy(r);
}

}  // namespace
