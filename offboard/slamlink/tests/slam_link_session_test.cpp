// SLAM-link session on real frames from tests/data, through the real protocol codec:
// SlamHello is answered; each RgbdFrame gets exactly one PoseUpdate for that pair_sequence; bad
// input is refused with a reason, never a crash.
#include <gtest/gtest.h>

#include "rgbdquad/protocol/codec.hpp"
#include "slam/dataset/tum_dataset.hpp"
#include "slam_link_session.hpp"

namespace slam {
namespace {

namespace proto = rgbdquad::protocol;
const std::string kExcerpt = std::string(SLAM_REPO_DIR) + "/tests/data/fr1_xyz_first30";

proto::RgbdFrame to_wire(const RgbdFrame& f, std::uint32_t seq) {
  proto::RgbdFrame m;
  m.pair_sequence = seq;
  m.intrinsics = {517.3, 516.5, 318.6, 255.3, {0, 0, 0, 0, 0}};
  m.depth_scale_units_per_m = 5000.0;
  auto header = [&](proto::PixelFormat fmt, std::size_t bytes) {
    proto::FrameHeader h;
    h.sequence = seq;
    h.capture_timestamp_us = static_cast<std::uint64_t>(f.stamp_s * 1e6);
    h.width = static_cast<std::uint16_t>(f.rgb.cols);
    h.height = static_cast<std::uint16_t>(f.rgb.rows);
    h.pixel_format = fmt;
    h.payload_length = static_cast<std::uint32_t>(bytes);
    return h;
  };
  const std::size_t n = static_cast<std::size_t>(f.rgb.total());
  m.rgb.payload.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Vec3b bgr = f.rgb.at<cv::Vec3b>(static_cast<int>(i));
    m.rgb.payload[3 * i] = bgr[2];
    m.rgb.payload[3 * i + 1] = bgr[1];
    m.rgb.payload[3 * i + 2] = bgr[0];
  }
  m.depth.payload.resize(2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t d = f.depth.at<std::uint16_t>(static_cast<int>(i));
    m.depth.payload[2 * i] = static_cast<std::uint8_t>(d & 0xFF);
    m.depth.payload[2 * i + 1] = static_cast<std::uint8_t>(d >> 8);
  }
  m.rgb.header = header(proto::PixelFormat::kRgb8, m.rgb.payload.size());
  m.depth.header = header(proto::PixelFormat::kDepth16, m.depth.payload.size());
  return m;
}

// Encodes, decodes through the stream decoder (as the server does), and hands to the session.
std::vector<proto::Message> roundtrip(SlamLinkSession* s, const proto::Message& m, std::string* err) {
  const proto::EncodeResult e = proto::encode(m);
  EXPECT_TRUE(e.ok()) << e.error;
  proto::StreamDecoder dec;
  dec.feed(e.bytes);
  proto::DecodeResult r = dec.next();
  EXPECT_EQ(r.status, proto::DecodeStatus::kMessage) << r.detail;
  if (!r.message) return {};
  bool fatal = false;
  return s->on_message(*r.message, err, &fatal);
}

TEST(SlamLinkSession, GivenHelloThenFramesWhenProcessedThenOnePoseUpdatePerFrame) {
  PipelineOptions o;
  o.frontend.features.kind = DetectorKind::kOrb;
  SlamLinkSession s(o, "test-server");
  std::string err;
  auto hello = roundtrip(&s, proto::SlamHello{proto::kProtocolVersion, proto::kSchemaHash, "quad-control"}, &err);
  ASSERT_EQ(hello.size(), 1u) << err;
  EXPECT_TRUE(std::holds_alternative<proto::SlamHello>(hello[0]));
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds) << err;
  for (std::uint32_t i = 0; i < 5; ++i) {
    auto f = ds->load(i, &err);
    ASSERT_TRUE(f) << err;
    auto replies = roundtrip(&s, to_wire(*f, 100 + i), &err);
    ASSERT_EQ(replies.size(), 1u) << err;
    const auto* u = std::get_if<proto::PoseUpdate>(&replies[0]);
    ASSERT_NE(u, nullptr);
    EXPECT_EQ(u->pair_sequence, 100 + i);
    EXPECT_EQ(u->tracking_state, i == 0 ? proto::TrackingState::kInitializing : proto::TrackingState::kTracking);
    if (i > 0) {
      EXPECT_GT(u->inlier_count, 50u);
    }
    EXPECT_TRUE(proto::validate(replies[0]).empty());
  }
  EXPECT_EQ(s.frames_processed(), 5u);
}

TEST(SlamLinkSession, GivenBadInputThenRefusedWithReason) {
  SlamLinkSession s(PipelineOptions{}, "test-server");
  std::string err;
  bool fatal = false;
  auto ds = TumDataset::open(kExcerpt, TumDatasetOptions{}, &err);
  ASSERT_TRUE(ds);
  auto f = ds->load(0, &err);
  ASSERT_TRUE(f);
  proto::RgbdFrame frame = to_wire(*f, 1);
  EXPECT_TRUE(s.on_message(frame, &err, &fatal).empty());  // no hello yet
  EXPECT_NE(err.find("before SlamHello"), std::string::npos);
  proto::SlamHello wrong{proto::kProtocolVersion, proto::kSchemaHash ^ 1u, "old-build"};
  EXPECT_TRUE(s.on_message(wrong, &err, &fatal).empty());
  EXPECT_TRUE(fatal);
  ASSERT_EQ(s.on_message(proto::SlamHello{proto::kProtocolVersion, proto::kSchemaHash, "ok"}, &err, &fatal).size(), 1u);
  proto::RgbdFrame truncated = frame;
  truncated.depth.payload.resize(100);
  EXPECT_TRUE(s.on_message(truncated, &err, &fatal).empty());
  EXPECT_NE(err.find("payload size"), std::string::npos);
  proto::RgbdFrame jpeg = frame;
  jpeg.rgb.header.encoding = proto::Encoding::kRgbJpeg;
  EXPECT_TRUE(s.on_message(jpeg, &err, &fatal).empty());
  EXPECT_NE(err.find("RAW"), std::string::npos);
}

}  // namespace
}  // namespace slam
