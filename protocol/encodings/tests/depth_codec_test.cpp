// Lossless depth codecs: bit-exact round trips on real TUM Kinect frames, and malformed payloads
// rejected without crashing.
#include "rgbdquad/encodings/depth_codec.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <random>

namespace rgbdquad::encodings {
namespace {

constexpr const char* kDepthPng = RGBD_TEST_DATA_DIR "/fr1_xyz_first30/depth/1305031102.160407.png";
constexpr const char* kDepthPng2 =
    RGBD_TEST_DATA_DIR "/fr1_desk_9frames/depth/1305031453.374112.png";
constexpr DepthCodec kAllCodecs[] = {DepthCodec::kRaw, DepthCodec::kRvl, DepthCodec::kZstdDelta,
                                     DepthCodec::kLz4Delta};

std::vector<std::uint16_t> load_depth(const char* path, int* width, int* height) {
  cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(m.type(), CV_16UC1) << path;
  *width = m.cols;
  *height = m.rows;
  return std::vector<std::uint16_t>(m.begin<std::uint16_t>(), m.end<std::uint16_t>());
}

TEST(DepthCodec, RoundTripIsBitExactOnRealFrames) {
  for (const char* path : {kDepthPng, kDepthPng2}) {
    int w = 0, h = 0;
    // GIVEN a real Kinect depth frame (with holes: zeros)
    const auto depth = load_depth(path, &w, &h);
    ASSERT_EQ(w * h, 640 * 480);
    ASSERT_GT(std::count(depth.begin(), depth.end(), 0), 0);
    for (DepthCodec codec : kAllCodecs) {
      // WHEN encoded and decoded
      const auto payload = encode_depth(codec, depth.data(), w, h);
      std::string error;
      const auto back = decode_depth(codec, payload.data(), payload.size(), w, h, &error);
      // THEN every pixel is identical
      ASSERT_TRUE(back.has_value()) << to_string(codec) << ": " << error;
      EXPECT_EQ(*back, depth) << to_string(codec);
      if (codec != DepthCodec::kRaw) {
        EXPECT_LT(payload.size(), depth.size()) << to_string(codec) << " does not compress";
      }
    }
  }
}

TEST(DepthCodec, RoundTripIsBitExactOnRandomExtremes) {
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> value(0, 65535);
  std::bernoulli_distribution hole(0.3);
  const int w = 37, h = 11;  // odd size: exercises partial RVL words
  std::vector<std::uint16_t> depth(w * h);
  for (auto& d : depth) d = hole(rng) ? 0 : static_cast<std::uint16_t>(value(rng));
  depth[0] = 65535;
  depth[1] = 1;
  for (DepthCodec codec : kAllCodecs) {
    const auto payload = encode_depth(codec, depth.data(), w, h);
    std::string error;
    const auto back = decode_depth(codec, payload.data(), payload.size(), w, h, &error);
    ASSERT_TRUE(back.has_value()) << to_string(codec) << ": " << error;
    EXPECT_EQ(*back, depth) << to_string(codec);
  }
}

TEST(DepthCodec, AllZeroAndConstantImagesRoundTrip) {
  const int w = 640, h = 480;
  for (std::uint16_t fill : {std::uint16_t{0}, std::uint16_t{1234}}) {
    std::vector<std::uint16_t> depth(w * h, fill);
    for (DepthCodec codec : kAllCodecs) {
      const auto payload = encode_depth(codec, depth.data(), w, h);
      const auto back = decode_depth(codec, payload.data(), payload.size(), w, h, nullptr);
      ASSERT_TRUE(back.has_value()) << to_string(codec);
      EXPECT_EQ(*back, depth);
    }
  }
}

TEST(DepthCodec, TruncatedOrCorruptPayloadIsRejectedNotCrashing) {
  int w = 0, h = 0;
  const auto depth = load_depth(kDepthPng, &w, &h);
  std::mt19937 rng(7);
  for (DepthCodec codec : kAllCodecs) {
    const auto payload = encode_depth(codec, depth.data(), w, h);
    std::string error;
    // Truncated by one byte and cut in half: always rejected with a message.
    for (std::size_t keep : {payload.size() - 1, payload.size() / 2, std::size_t{0}}) {
      error.clear();
      EXPECT_FALSE(decode_depth(codec, payload.data(), keep, w, h, &error).has_value())
          << to_string(codec) << " accepted " << keep << " of " << payload.size() << " bytes";
      EXPECT_FALSE(error.empty());
    }
    // Wrong image size in the header: rejected.
    EXPECT_FALSE(decode_depth(codec, payload.data(), payload.size(), w, h + 1, &error));
    EXPECT_FALSE(decode_depth(codec, payload.data(), payload.size(), -1, h, &error));
    // Random byte flips: may decode to something (raw has no redundancy) but must not crash.
    for (int trial = 0; trial < 50; ++trial) {
      auto bad = payload;
      bad[std::uniform_int_distribution<std::size_t>(0, bad.size() - 1)(rng)] ^= 0x5A;
      (void)decode_depth(codec, bad.data(), bad.size(), w, h, &error);
    }
  }
}

TEST(DepthCodec, NamesRoundTrip) {
  for (DepthCodec codec : kAllCodecs) {
    EXPECT_EQ(depth_codec_from_string(to_string(codec)), codec);
  }
  EXPECT_FALSE(depth_codec_from_string("png").has_value());
}

}  // namespace
}  // namespace rgbdquad::encodings
