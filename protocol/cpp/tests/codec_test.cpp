// Round trips of every message, envelope layout byte by byte, and hostile input to the
// StreamDecoder (truncation at every length, corruption, garbage, oversized lengths, chunking).
#include "rgbdquad/protocol/codec.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "json_view.hpp"
#include "rgbdquad/camera/tum_cameras.hpp"

namespace rgbdquad::protocol {
namespace {

std::vector<std::uint8_t> must_encode(const Message& m) {
  EncodeResult r = encode(m);
  EXPECT_TRUE(r.ok()) << r.error;
  return r.bytes;
}

Frame make_rgb_frame(std::uint16_t w, std::uint16_t h, std::uint32_t seq) {
  Frame f;
  f.image.header = {
      seq, 1'000'000u + seq,   2'000'000u + seq, w,
      h,   PixelFormat::kRgb8, Encoding::kRaw,   static_cast<std::uint32_t>(w * h * 3)};
  f.image.payload.resize(std::size_t{w} * h * 3);
  for (std::size_t i = 0; i < f.image.payload.size(); ++i)
    f.image.payload[i] = static_cast<std::uint8_t>(i * 7 + seq);
  return f;
}

Handshake make_handshake() {
  Handshake h;
  h.stream_kind = StreamKind::kDepth;
  h.width = 640;
  h.height = 480;
  h.pixel_format = PixelFormat::kDepth16;
  h.encoding = Encoding::kRaw;
  const camera::TumCamera& fr1 = camera::kTumFr1;
  h.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, fr1.distortion};
  h.depth_scale_units_per_m = camera::kTumDepthUnitsPerM;
  h.device_id = "kinect-A00364A09418042A";
  return h;
}

PoseGraph make_graph(std::size_t nodes) {
  PoseGraph g;
  g.revision = 3;
  g.timestamp_us = 1305031102175304;
  g.stage = GraphStage::kAfterOptimisation;
  for (std::size_t i = 0; i < nodes; ++i) {
    PoseGraphNode n;
    n.node_id = static_cast<std::uint32_t>(i);
    n.timestamp_us = 1000 * i;
    n.T_world_node.t_m = {0.1 * double(i), -0.2, 1.5};
    g.nodes.push_back(n);
    if (i > 0) {
      PoseGraphEdge e;
      e.from_id = static_cast<std::uint32_t>(i - 1);
      e.to_id = static_cast<std::uint32_t>(i);
      e.T_from_to.t_m = {0.1, 0.0, 0.0};
      g.edges.push_back(e);
    }
  }
  return g;
}

std::vector<Message> all_message_kinds() {
  std::vector<Message> out;
  out.emplace_back(make_handshake());
  out.emplace_back(HandshakeAck{false, "schema hash mismatch"});
  out.emplace_back(make_rgb_frame(4, 3, 7));
  out.emplace_back(FrameRequest{2, 41});
  out.emplace_back(SlamHello{kProtocolVersion, kSchemaHash, "slam-server", 0x1234, true, 205, ""});
  RgbdFrame pair;
  pair.pair_sequence = 9;
  pair.intrinsics = make_handshake().intrinsics;
  pair.depth_scale_units_per_m = camera::kTumDepthUnitsPerM;
  pair.rgb = make_rgb_frame(2, 2, 1).image;
  pair.depth.header = {1, 5, 6, 2, 2, PixelFormat::kDepth16, Encoding::kRaw, 8};
  pair.depth.payload = {1, 2, 3, 4, 5, 6, 7, 8};
  out.emplace_back(pair);
  pair.attitude = {true, {0.5, 0.5, 0.5, 0.5}};  // the camera's IMU attitude rides along
  out.emplace_back(pair);
  PoseUpdate pose;
  pose.pair_sequence = 9;
  pose.timestamp_us = 1305031102175304;
  pose.tracking_state = TrackingState::kTracking;
  pose.T_world_cam = {{1.3405, 0.6266, 1.6575}, {0.6574, 0.6126, -0.2949, -0.3248}};
  pose.is_keyframe = true;
  pose.inlier_count = 312;
  pose.map_correction_count = 2;
  const double n2 = 0.6574 * 0.6574 + 0.6126 * 0.6126 + 0.2949 * 0.2949 + 0.3248 * 0.3248;
  for (double& q : pose.T_world_cam.q_xyzw) q /= std::sqrt(n2);
  out.emplace_back(pose);
  out.emplace_back(make_graph(5));
  FloorMap map;
  map.width_cells = 3;
  map.height_cells = 2;
  map.cells = {0, 100, 255, 0, 50, 255};
  out.emplace_back(map);
  return out;
}

TEST(Crc32, MatchesTheZlibCheckValue) {
  const char* check = "123456789";
  EXPECT_EQ(crc32(reinterpret_cast<const std::uint8_t*>(check), 9), 0xCBF43926u);
  // Incremental equals one shot.
  const auto* p = reinterpret_cast<const std::uint8_t*>(check);
  EXPECT_EQ(crc32(p + 4, 5, crc32(p, 4)), 0xCBF43926u);
}

TEST(Envelope, HeaderLayoutIsExplicitLittleEndian) {
  // GIVEN a FrameRequest WHEN encoded THEN the header bytes are exactly as documented.
  const auto bytes = must_encode(FrameRequest{3, 0x01020304});
  ASSERT_EQ(bytes.size(), 16u + 6u + 4u);
  EXPECT_EQ(std::memcmp(bytes.data(), "RGBQ", 4), 0);
  EXPECT_EQ(bytes[4], kProtocolVersion);
  EXPECT_EQ(bytes[5], 4);  // FrameRequest
  EXPECT_EQ(bytes[6], 0);
  EXPECT_EQ(bytes[7], 0);
  EXPECT_EQ(bytes[8], 6);  // body_length LE
  EXPECT_EQ(bytes[9] | bytes[10] | bytes[11], 0);
  const std::uint32_t hcrc = crc32(bytes.data(), 12);
  EXPECT_EQ(bytes[12], hcrc & 0xFF);
  EXPECT_EQ(bytes[15], hcrc >> 24);
  const std::vector<std::uint8_t> body = {3, 0, 4, 3, 2, 1};
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin() + 16, bytes.begin() + 22), body);
  const std::uint32_t bcrc = crc32(body.data(), body.size());
  EXPECT_EQ(bytes[22] | bytes[23] << 8 | bytes[24] << 16 | std::uint32_t{bytes[25]} << 24, bcrc);
}

TEST(RoundTrip, EveryMessageKindDecodesToTheSameBytesAndView) {
  for (const Message& m : all_message_kinds()) {
    const auto bytes = must_encode(m);
    StreamDecoder decoder;
    decoder.feed(bytes);
    DecodeResult r = decoder.next();
    ASSERT_EQ(r.status, DecodeStatus::kMessage)
        << to_string(message_type(m)) << ": " << to_string(r.error) << " " << r.detail;
    EXPECT_EQ(to_json(*r.message), to_json(m));
    EXPECT_EQ(must_encode(*r.message), bytes);
    EXPECT_EQ(decoder.next().status, DecodeStatus::kNeedMoreBytes);
    EXPECT_EQ(decoder.buffered_bytes(), 0u);
  }
}

TEST(RoundTrip, FullSizeKinectFramesAndAMaximalPoseGraph) {
  const Frame rgb = make_rgb_frame(640, 480, 123);
  Frame depth;
  depth.image.header = {5, 6, 7, 640, 480, PixelFormat::kDepth16, Encoding::kRaw, 640 * 480 * 2};
  depth.image.payload.assign(640 * 480 * 2, 0xAB);
  for (const Message& m : {Message{rgb}, Message{depth}, Message{make_graph(kMaxGraphNodes)}}) {
    const auto bytes = must_encode(m);
    StreamDecoder decoder;
    decoder.feed(bytes);
    DecodeResult r = decoder.next();
    ASSERT_EQ(r.status, DecodeStatus::kMessage) << r.detail;
    EXPECT_EQ(must_encode(*r.message), bytes);
  }
}

TEST(Encode, RejectsMessagesThatBreakTheSpec) {
  struct Case {
    const char* name;
    Message message;
    const char* field;
  };
  Frame wrong_size = make_rgb_frame(4, 3, 0);
  wrong_size.image.payload.pop_back();
  wrong_size.image.header.payload_length -= 1;
  Frame bad_length = make_rgb_frame(4, 3, 0);
  bad_length.image.header.payload_length = 1;
  Frame jpeg_depth = make_rgb_frame(4, 3, 0);
  jpeg_depth.image.header.pixel_format = PixelFormat::kDepth16;
  jpeg_depth.image.header.encoding = Encoding::kRgbJpeg;
  Handshake nan_fx = make_handshake();
  nan_fx.intrinsics.fx_px = std::numeric_limits<double>::quiet_NaN();
  Handshake long_id = make_handshake();
  long_id.device_id = std::string(256, 'x');
  Handshake kind_mismatch = make_handshake();
  kind_mismatch.stream_kind = StreamKind::kRgb;
  PoseUpdate bad_q;
  bad_q.T_world_cam.q_xyzw = {0, 0, 0, 0.5};
  RgbdFrame bad_attitude;
  bad_attitude.intrinsics = make_handshake().intrinsics;
  bad_attitude.depth_scale_units_per_m = camera::kTumDepthUnitsPerM;
  bad_attitude.rgb = make_rgb_frame(2, 2, 1).image;
  bad_attitude.depth.header = {1, 5, 6, 2, 2, PixelFormat::kDepth16, Encoding::kRaw, 8};
  bad_attitude.depth.payload = {1, 2, 3, 4, 5, 6, 7, 8};
  bad_attitude.attitude = {true, {0, 0, 0, 0.5}};
  FloorMap short_cells;
  short_cells.width_cells = 2;
  short_cells.height_cells = 2;
  short_cells.cells = {0, 0, 0};
  const Case cases[] = {
      {"raw payload size", wrong_size, "payload"},
      {"payload_length mismatch", bad_length, "payload_length"},
      {"encoding/pixel format", jpeg_depth, "encoding"},
      {"non-finite intrinsics", nan_fx, "fx_px"},
      {"string too long", long_id, "device_id"},
      {"stream kind mismatch", kind_mismatch, "stream_kind"},
      {"credits 0", FrameRequest{0, 0}, "credits"},
      {"credits above max", FrameRequest{9, 0}, "credits"},
      {"non-unit quaternion", bad_q, "q_xyzw"},
      {"non-unit attitude", bad_attitude, "attitude.q_xyzw"},
      {"map cells size", short_cells, "cells"},
  };
  for (const Case& c : cases) {
    const EncodeResult r = encode(c.message);
    EXPECT_FALSE(r.ok()) << c.name;
    EXPECT_TRUE(r.bytes.empty()) << c.name;
    EXPECT_NE(r.error.find(c.field), std::string::npos) << c.name << ": " << r.error;
  }
}

TEST(Encode, HeaderAndPointerOverloadEqualsTheFrameOverload) {
  const Frame f = make_rgb_frame(6, 5, 3);
  const EncodeResult a = encode_frame(f);
  const EncodeResult b =
      encode_frame(f.image.header, f.image.payload.data(), f.image.payload.size());
  ASSERT_TRUE(a.ok() && b.ok()) << a.error << b.error;
  EXPECT_EQ(a.bytes, b.bytes);
  // WHEN payload_length disagrees with the size given THEN it refuses, naming the field.
  const EncodeResult c = encode_frame(f.image.header, f.image.payload.data(), 10);
  EXPECT_FALSE(c.ok());
  EXPECT_NE(c.error.find("payload"), std::string::npos);
  FrameHeader h = f.image.header;
  h.payload_length = 4;
  h.encoding = Encoding::kRgbJpeg;
  EXPECT_FALSE(encode_frame(h, nullptr, 4).ok());
}

TEST(StreamDecoder, EveryTruncationNeedsMoreBytesAndThenDecodes) {
  const auto bytes = must_encode(make_handshake());
  for (std::size_t cut = 0; cut < bytes.size(); ++cut) {
    StreamDecoder decoder;
    decoder.feed(bytes.data(), cut);
    EXPECT_EQ(decoder.next().status, DecodeStatus::kNeedMoreBytes) << cut;
    decoder.feed(bytes.data() + cut, bytes.size() - cut);
    EXPECT_EQ(decoder.next().status, DecodeStatus::kMessage) << cut;
  }
}

TEST(StreamDecoder, ByteByByteFeedingYieldsEveryMessageInOrder) {
  std::vector<std::uint8_t> stream;
  const auto messages = all_message_kinds();
  for (const Message& m : messages) {
    const auto b = must_encode(m);
    stream.insert(stream.end(), b.begin(), b.end());
  }
  StreamDecoder decoder;
  std::size_t got = 0;
  for (std::uint8_t byte : stream) {
    decoder.feed(&byte, 1);
    for (DecodeResult r = decoder.next(); r.status != DecodeStatus::kNeedMoreBytes;
         r = decoder.next()) {
      ASSERT_EQ(r.status, DecodeStatus::kMessage) << to_string(r.error);
      EXPECT_EQ(message_type(*r.message), message_type(messages[got]));
      ++got;
    }
  }
  EXPECT_EQ(got, messages.size());
}

TEST(StreamDecoder, GarbageBeforeAFrameIsSkippedThenTheFrameDecodes) {
  std::vector<std::uint8_t> stream = {'x', 'R', 'G', 'B', 0, 'R', 'G'};
  const auto frame = must_encode(FrameRequest{1, 5});
  stream.insert(stream.end(), frame.begin(), frame.end());
  StreamDecoder decoder;
  decoder.feed(stream);
  DecodeResult r = decoder.next();
  EXPECT_EQ(r.status, DecodeStatus::kError);
  EXPECT_EQ(r.error, DecodeError::kGarbageSkipped);
  EXPECT_EQ(r.bytes_discarded, 7u);
  EXPECT_EQ(decoder.next().status, DecodeStatus::kMessage);
}

TEST(StreamDecoder, CorruptLengthIsCaughtByTheHeaderCrcWithoutWaiting) {
  auto bytes = must_encode(make_rgb_frame(4, 3, 0));
  bytes[10] ^= 0x40;  // body_length += 4 MiB
  const auto good = must_encode(FrameRequest{1, 0});
  bytes.insert(bytes.end(), good.begin(), good.end());
  StreamDecoder decoder;
  decoder.feed(bytes);
  DecodeResult r = decoder.next();
  EXPECT_EQ(r.error, DecodeError::kBadHeaderCrc);
  EXPECT_EQ(r.bytes_discarded, bytes.size() - good.size());
  EXPECT_EQ(decoder.next().status, DecodeStatus::kMessage);
}

TEST(StreamDecoder, OversizedBodyLengthWithValidHeaderCrcIsRefusedBeforeWaiting) {
  auto bytes = must_encode(FrameRequest{1, 0});
  const std::uint32_t huge = 0xFFFFFFF0u;
  for (int i = 0; i < 4; ++i) bytes[8 + i] = static_cast<std::uint8_t>(huge >> (8 * i));
  const std::uint32_t hcrc = crc32(bytes.data(), 12);
  for (int i = 0; i < 4; ++i) bytes[12 + i] = static_cast<std::uint8_t>(hcrc >> (8 * i));
  StreamDecoder decoder;
  decoder.feed(bytes.data(), 16);
  DecodeResult r = decoder.next();
  EXPECT_EQ(r.error, DecodeError::kBodyTooLarge);
}

TEST(StreamDecoder, OptionCapsBodyBelowTheSpecMaximum) {
  const auto bytes = must_encode(make_rgb_frame(8, 8, 0));
  StreamDecoder decoder(StreamDecoder::Options{64});
  decoder.feed(bytes);
  EXPECT_EQ(decoder.next().error, DecodeError::kBodyTooLarge);
}

TEST(StreamDecoder, BadBodyCrcDropsExactlyOneFrame) {
  auto first = must_encode(make_rgb_frame(4, 3, 0));
  first[20] ^= 1;
  const auto second = must_encode(make_rgb_frame(4, 3, 1));
  std::vector<std::uint8_t> stream = first;
  stream.insert(stream.end(), second.begin(), second.end());
  StreamDecoder decoder;
  decoder.feed(stream);
  DecodeResult r = decoder.next();
  EXPECT_EQ(r.error, DecodeError::kBadBodyCrc);
  EXPECT_EQ(r.bytes_discarded, first.size());
  r = decoder.next();
  ASSERT_EQ(r.status, DecodeStatus::kMessage);
  EXPECT_EQ(std::get<Frame>(*r.message).image.header.sequence, 1u);
}

TEST(StreamDecoder, SeededRandomCorruptionNeverCrashesAndLaterFramesSurvive) {
  std::mt19937 rng(1234);
  const auto good = must_encode(make_graph(3));
  for (int trial = 0; trial < 500; ++trial) {
    std::vector<std::uint8_t> bad = must_encode(make_rgb_frame(4, 3, 0));
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int i = 0; i < flips; ++i)
      bad[rng() % bad.size()] ^= static_cast<std::uint8_t>(1 + rng() % 255);
    StreamDecoder decoder;
    decoder.feed(bad);
    decoder.feed(good);
    int messages = 0;
    for (int guard = 0; guard < 100; ++guard) {
      DecodeResult r = decoder.next();
      if (r.status == DecodeStatus::kNeedMoreBytes) break;
      if (r.status == DecodeStatus::kMessage) ++messages;
    }
    // The good frame always decodes; the corrupt one only if the flips cancelled out (never here).
    EXPECT_GE(messages, 1) << trial;
    EXPECT_EQ(decoder.buffered_bytes(), 0u) << trial;
  }
}

TEST(DecodeBody, HostileArrayCountIsRefusedBeforeAllocating) {
  // revision, timestamp, stage, then nodes count 0xFFFFFFFF with no node bytes.
  std::vector<std::uint8_t> body(4 + 8 + 1, 0);
  body.insert(body.end(), {0xFF, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(decode_body(19, body.data(), body.size()).error, DecodeError::kLengthTooLarge);
  // A count within the limit but beyond the bytes present is a truncation.
  body.resize(13);
  body.insert(body.end(), {0x00, 0x40, 0x00, 0x00});  // 16384 nodes, no bytes
  EXPECT_EQ(decode_body(19, body.data(), body.size()).error, DecodeError::kTruncatedBody);
}

TEST(Compatibility, MismatchedHashOrVersionIsRefusedLoudly) {
  Handshake h = make_handshake();
  EXPECT_EQ(handshake_incompatibility(h), "");
  h.schema_hash ^= 1;
  EXPECT_NE(handshake_incompatibility(h).find("schema hash mismatch"), std::string::npos);
  h = make_handshake();
  h.protocol_version = kProtocolVersion + 1;
  EXPECT_NE(handshake_incompatibility(h).find("version"), std::string::npos);
  // An older decoded version is accepted with its own schema hash only (a craft running the
  // previous streamer must still fly).
  h = make_handshake();
  h.protocol_version = kOldestDecodedProtocolVersion;
  EXPECT_NE(handshake_incompatibility(h).find("schema hash mismatch"), std::string::npos);
  h.schema_hash = schema_hash_of_version(kOldestDecodedProtocolVersion);
  EXPECT_EQ(handshake_incompatibility(h), "");
  SlamHello hello{kProtocolVersion, kSchemaHash + 1, "x", 0, false, 0, ""};
  EXPECT_NE(hello_incompatibility(hello), "");
}

TEST(Versions, OldVersionFrameDecodesWithoutAccelAndReencodesInItsVersion) {
  // GIVEN a frame with an accelerometer sample, encoded as the current and the oldest version
  Frame f = make_rgb_frame(4, 3, 7);
  f.accel = {true, f.image.header.capture_timestamp_us, {0.1, 9.8, -0.4}};
  const EncodeResult now = encode(f);
  const EncodeResult old = encode(f, kOldestDecodedProtocolVersion);
  ASSERT_TRUE(now.ok() && old.ok());
  EXPECT_EQ(old.bytes[4], kOldestDecodedProtocolVersion);
  EXPECT_EQ(now.bytes.size(), old.bytes.size() + 1 + 8 + 3 * 8);  // the AccelSample
  // WHEN both are decoded from one stream
  StreamDecoder decoder;
  decoder.feed(now.bytes);
  decoder.feed(old.bytes);
  const DecodeResult a = decoder.next();
  const DecodeResult b = decoder.next();
  ASSERT_EQ(a.status, DecodeStatus::kMessage);
  ASSERT_EQ(b.status, DecodeStatus::kMessage);
  // THEN the current one keeps its sample, the old one has none, and each re-encodes as it came
  EXPECT_EQ(a.version, kProtocolVersion);
  EXPECT_EQ(b.version, kOldestDecodedProtocolVersion);
  EXPECT_TRUE(std::get<Frame>(*a.message).accel.valid);
  EXPECT_EQ(std::get<Frame>(*a.message).accel.f_mps2[1], 9.8);
  EXPECT_FALSE(std::get<Frame>(*b.message).accel.valid);
  EXPECT_EQ(encode(*b.message, b.version).bytes, old.bytes);
  // AND the hot-path encoder writes the same bytes as the message encoder
  EXPECT_EQ(
      encode_frame(f.image.header, f.image.payload.data(), f.image.payload.size(), f.accel).bytes,
      now.bytes);
}

TEST(Versions, NonFiniteOrOutOfRangeAccelIsRefusedBothWays) {
  Frame f = make_rgb_frame(4, 3, 7);
  f.accel = {true, 1, {0.0, std::nan(""), 0.0}};
  EXPECT_NE(encode(f).error.find("accel.f_mps2"), std::string::npos);
  f.accel.f_mps2 = {0.0, 0.0, 5000.0};
  EXPECT_FALSE(encode(f).ok());
  EXPECT_FALSE(
      encode_frame(f.image.header, f.image.payload.data(), f.image.payload.size(), f.accel).ok());
  EXPECT_FALSE(encode(f, kProtocolVersion + 1).ok());  // a version this build does not write
}

}  // namespace
}  // namespace rgbdquad::protocol
