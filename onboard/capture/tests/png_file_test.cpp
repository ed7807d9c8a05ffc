// libpng reader on the shipped TUM frames. Expected figures were computed independently with
// Pillow + numpy (`np.array(Image.open(path))`): sums, hole count and sample pixels, so a
// byte-order, channel-order or row-stride error fails here on every architecture (also under qemu
// on ARM).
#include "rgbdquad/capture/png_file.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <numeric>

namespace rgbdquad::capture {
namespace {

constexpr const char* kDepthPng = RGBD_TEST_DATA_DIR "/fr1_xyz_first30/depth/1305031102.160407.png";
constexpr const char* kRgbPng = RGBD_TEST_DATA_DIR "/fr1_xyz_first30/rgb/1305031102.175304.png";

TEST(PngFile, DepthMatchesAnIndependentDecoder) {
  std::string error;
  const auto png = read_png_gray16(kDepthPng, &error);
  ASSERT_TRUE(png.has_value()) << error;
  ASSERT_EQ(png->width, 640);
  ASSERT_EQ(png->height, 480);
  const auto& d = png->pixels;
  EXPECT_EQ(std::accumulate(d.begin(), d.end(), std::int64_t{0}), 1640368667);
  EXPECT_EQ(std::count(d.begin(), d.end(), 0), 77325);
  EXPECT_EQ(d[240 * 640 + 320], 5287);
}

TEST(PngFile, RgbMatchesAnIndependentDecoder) {
  std::string error;
  const auto png = read_png_rgb8(kRgbPng, &error);
  ASSERT_TRUE(png.has_value()) << error;
  ASSERT_EQ(png->width, 640);
  ASSERT_EQ(png->height, 480);
  const auto& p = png->pixels;
  ASSERT_EQ(p.size(), 640u * 480u * 3u);
  const std::int64_t expected_sums[3] = {44413575, 41312886, 42706047};  // R, G, B
  for (int c = 0; c < 3; ++c) {
    std::int64_t sum = 0;
    for (std::size_t i = static_cast<std::size_t>(c); i < p.size(); i += 3) sum += p[i];
    EXPECT_EQ(sum, expected_sums[c]) << "channel " << c;
  }
  const std::size_t last = (479u * 640u + 639u) * 3u;
  EXPECT_EQ(std::vector<int>(p.begin(), p.begin() + 3), (std::vector<int>{137, 124, 126}));
  EXPECT_EQ(std::vector<int>(p.begin() + last, p.begin() + last + 3),
            (std::vector<int>{232, 218, 238}));
}

TEST(PngFile, WrongKindMissingAndTruncatedFilesAreErrorsNotCrashes) {
  std::string error;
  EXPECT_FALSE(read_png_gray16(kRgbPng, &error).has_value());
  EXPECT_NE(error.find("16-bit grey"), std::string::npos) << error;
  EXPECT_FALSE(read_png_rgb8("/nonexistent/x.png", &error).has_value());
  EXPECT_NE(error.find("cannot open"), std::string::npos) << error;
  // A PNG cut in the middle of its image data: libpng's error path, no partial frame.
  std::ifstream in(kDepthPng, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cut = ::testing::TempDir() + "png_file_test_truncated.png";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  error.clear();
  EXPECT_FALSE(read_png_gray16(cut, &error).has_value());
  EXPECT_FALSE(error.empty());
  std::remove(cut.c_str());
}

}  // namespace
}  // namespace rgbdquad::capture
