// Depth-to-RGB registration: identity keeps the image; a baseline shifts a fronto-parallel plane
// by fx*b/Z pixels; a nearer surface occludes a farther one.
#include "rgbdquad/capture/depth_registration.h"

#include <gtest/gtest.h>

#include <cmath>

#include "rgbdquad/camera/tum_cameras.hpp"

namespace rgbdquad::capture {
namespace {

RegistrationOptions same_camera() {
  RegistrationOptions o;
  const camera::TumCamera& kinect = camera::kTumRosDefault;
  o.depth = {kinect.fx_px, kinect.fy_px, kinect.cx_px, kinect.cy_px};
  o.rgb = o.depth;
  o.t_rgb_depth_m = {0, 0, 0};
  return o;
}

DepthFrame plane(std::uint16_t mm) {
  DepthFrame f;
  f.capture_timestamp_us = 123;
  f.width = 640;
  f.height = 480;
  f.depth.assign(640 * 480, mm);
  return f;
}

TEST(DepthRegistration, IdentityKeepsEveryPixel) {
  DepthFrame in = plane(0);
  for (std::size_t i = 0; i < in.depth.size(); i += 7)
    in.depth[i] = static_cast<std::uint16_t>(500 + i % 3000);
  const auto out = DepthRegistration(same_camera()).register_depth(in);
  ASSERT_TRUE(out.has_value());
  EXPECT_EQ(out->depth, in.depth);
  EXPECT_TRUE(out->registered_to_rgb);
  EXPECT_EQ(out->capture_timestamp_us, 123);
}

TEST(DepthRegistration, BaselineShiftsPlaneByDisparity) {
  // GIVEN a plane at 2 m and an RGB camera 50 mm to the depth camera's left (t_x = +0.05 m)
  auto options = same_camera();
  options.t_rgb_depth_m = {0.05, 0, 0};
  // THEN every pixel moves right by fx * b / Z = 525 * 0.05 / 2 = 13.125 -> 13 px
  const auto out = DepthRegistration(options).register_depth(plane(2000));
  ASSERT_TRUE(out.has_value());
  const int row = 240;
  for (int u = 0; u < 13; ++u) EXPECT_EQ(out->depth[row * 640 + u], 0) << u;
  for (int u = 13; u < 640; ++u) ASSERT_EQ(out->depth[row * 640 + u], 2000) << u;
}

TEST(DepthRegistration, NearerSurfaceWins) {
  auto options = same_camera();
  options.t_rgb_depth_m = {0.05, 0, 0};
  DepthFrame in = plane(0);
  // far point at u=300 (4 m, shifts 6.56 -> 7 px to 307); near point at u=287 (1 m, shifts 26.25
  // -> 26 px... lands at 313); put the near one where it lands on 307: u = 307 - 26 = 281
  in.depth[240 * 640 + 300] = 4000;
  in.depth[240 * 640 + 281] = 1000;
  const auto out = DepthRegistration(options).register_depth(in);
  ASSERT_TRUE(out.has_value());
  EXPECT_EQ(out->depth[240 * 640 + 307], 1000);
}

TEST(DepthRegistration, RejectsBadInputAndOptions) {
  DepthFrame bad = plane(1000);
  bad.depth.resize(10);
  EXPECT_FALSE(DepthRegistration(same_camera()).register_depth(bad).has_value());
  auto options = same_camera();
  options.depth.fx_px = 0;
  std::string error;
  EXPECT_FALSE(options.is_valid(&error));
  options = same_camera();
  options.t_rgb_depth_m[1] = std::nan("");
  EXPECT_FALSE(options.is_valid(&error));
}

}  // namespace
}  // namespace rgbdquad::capture
