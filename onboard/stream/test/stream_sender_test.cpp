// Sender pieces without sockets: the pair-aware frame choice and the payload encoder's contract.
#include <gtest/gtest.h>

#include "rgbdquad/encodings/depth_codec.h"
#include "rgbdquad/stream/payload_encoder.h"
#include "rgbdquad/stream/stream_sender.h"

namespace rgbdquad::stream {
namespace {

TEST(ChooseFrame, TableOfHints) {
  const std::vector<std::int64_t> held = {1000, 34000, 67000, 100000};  // 30 fps depth
  struct Case {
    const char* name;
    std::int64_t hint, used_before;
    std::size_t expected;
  };
  const Case cases[] = {
      {"no RGB sent yet: newest", PairHint::kNone, PairHint::kNone, 3},
      {"new RGB at 40 ms: its nearest depth", 40000, PairHint::kNone, 1},
      {"same RGB as last time: newest", 40000, 40000, 3},
      {"RGB newer than every depth: newest", 500000, 40000, 3},
      {"RGB older than every depth: oldest", -5000, 40000, 0},
      {"tie: the newer one", 50500, 0, 2},
  };
  for (const auto& c : cases) EXPECT_EQ(choose_frame(held, c.hint, c.used_before), c.expected) << c.name;
}

TEST(PayloadEncoder, EncodesOnlyItsKindInItsEncoding) {
  capture::DepthFrame depth;
  depth.width = 4;
  depth.height = 2;
  depth.depth = {0, 1000, 1001, 0, 5, 65535, 0, 7};
  capture::RgbFrame rgb;
  rgb.width = 4;
  rgb.height = 2;
  rgb.rgb.assign(24, 9);
  PayloadEncoder rvl(protocol::StreamKind::kDepth, protocol::Encoding::kDepthRvl, 90, 1);
  std::string error;
  const auto payload = rvl.encode(depth, &error);
  ASSERT_TRUE(payload.has_value()) << error;
  const auto back = encodings::decode_depth(encodings::DepthCodec::kRvl, payload->data(), payload->size(), 4, 2, &error);
  ASSERT_TRUE(back.has_value()) << error;
  EXPECT_EQ(*back, depth.depth);
  EXPECT_FALSE(rvl.encode(rgb, &error).has_value());
  EXPECT_NE(error.find("RGB frame given to the depth stream"), std::string::npos);
  PayloadEncoder raw_rgb(protocol::StreamKind::kRgb, protocol::Encoding::kRaw, 90, 1);
  EXPECT_EQ(*raw_rgb.encode(rgb, &error), rgb.rgb);
  EXPECT_THROW(PayloadEncoder(protocol::StreamKind::kRgb, protocol::Encoding::kDepthRvl, 90, 1), std::invalid_argument);
  EXPECT_EQ(depth_encoding_from_string("zstd-delta"), protocol::Encoding::kDepthZstdDelta);
  EXPECT_FALSE(rgb_encoding_from_string("rvl").has_value());
}

}  // namespace
}  // namespace rgbdquad::stream
