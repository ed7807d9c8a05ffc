// End to end on loopback: the real onboard StreamSender/StreamerPipeline against StreamReceiver,
// plus raw-socket peers for the cases a well-behaved peer cannot produce (corrupt bytes, a
// receiver that withholds credits, a mismatched schema).
#include <gtest/gtest.h>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/net/socket.h"
#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/receiver/stream_receiver.h"
#include "rgbdquad/stream/pipeline.h"
#include "rgbdquad/stream/stream_sender.h"
#include "test_support.h"

namespace rgbdquad {
namespace {

using protocol::Encoding;
using protocol::StreamKind;
using testing::eventually;

constexpr const char* kDesk = RGBD_TEST_DATA_DIR "/fr1_desk_9frames";

receiver::ReceiverOptions loopback_receiver(std::uint16_t rgb_port = 0,
                                            std::uint16_t depth_port = 0) {
  receiver::ReceiverOptions o;
  o.bind_address = "127.0.0.1";
  o.rgb_port = rgb_port;
  o.depth_port = depth_port;
  o.key = protocol::testing::kTestStreamKey;
  return o;
}

stream::StreamSenderOptions sender_options(StreamKind kind, std::uint16_t port, Encoding encoding) {
  stream::StreamSenderOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  o.kind = kind;
  o.encoding = encoding;
  const camera::TumCamera& fr1 = camera::kTumFr1;
  o.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, {}};
  o.depth_units_per_m = capture::kTumDepthUnitsPerM;
  o.backoff_first_ms = 5;
  o.backoff_max_ms = 100;
  o.key = protocol::testing::kTestStreamKey;
  return o;
}

// Two distinct free ports: both probes stay bound until both are read, because the kernel may hand
// a port that was just released to the very next bind (it did, in CI).
std::pair<std::uint16_t, std::uint16_t> two_free_ports() {
  const net::UniqueFd first = net::listen_tcp("127.0.0.1", 0);
  const net::UniqueFd second = net::listen_tcp("127.0.0.1", 0);
  return {net::local_port(first), net::local_port(second)};
}

TEST(StreamEndToEnd, RealFramesArriveDepthBitExactAndPaired) {
  capture::SteadyClock clock;
  const auto frames = testing::load_tum(kDesk);
  ASSERT_EQ(frames.size(), 18u);
  for (Encoding depth_encoding : {Encoding::kDepthRvl, Encoding::kDepthZstdDelta, Encoding::kRaw}) {
    receiver::StreamReceiver rx(loopback_receiver(), testing::steady_now_us(), nullptr);
    stream::StreamSender rgb(sender_options(StreamKind::kRgb, rx.rgb_port(), Encoding::kRgbJpeg),
                             &clock, nullptr);
    stream::StreamSender depth(sender_options(StreamKind::kDepth, rx.depth_port(), depth_encoding),
                               &clock, nullptr);
    testing::ScriptedSource source(frames);
    stream::StreamerPipeline pipeline(&source, {}, std::nullopt, &rgb, &depth);
    // One frame at a time, waiting for its arrival: every frame must come through.
    for (const auto& expected : frames) {
      ASSERT_TRUE(pipeline.step());
      if (const auto* d = std::get_if<capture::DepthFrame>(&expected)) {
        ASSERT_TRUE(eventually([&] {
          auto got = rx.newest_depth();
          return got && got->info.capture_timestamp_us == d->capture_timestamp_us;
        })) << "depth frame did not arrive";
        const auto got = rx.newest_depth();
        EXPECT_EQ(got->depth, d->depth) << "lossless depth must be bit-exact";
        EXPECT_EQ(got->units_per_m, capture::kTumDepthUnitsPerM);
        EXPECT_EQ(got->info.encoding, depth_encoding);
      } else {
        const auto& r = std::get<capture::RgbFrame>(expected);
        ASSERT_TRUE(eventually([&] {
          auto got = rx.newest_rgb();
          return got && got->info.capture_timestamp_us == r.capture_timestamp_us;
        }));
        EXPECT_EQ(rx.newest_rgb()->rgb.size(), r.rgb.size());
      }
    }
    const auto pair = rx.newest_pair();
    ASSERT_TRUE(pair.has_value());
    EXPECT_LE(pair->gap_us(), 20000);
    EXPECT_DOUBLE_EQ(pair->intrinsics.fx_px, camera::kTumFr1.fx_px);
    const auto c = rx.counters();
    EXPECT_EQ(c.rgb.frames, 9u);
    EXPECT_EQ(c.depth.frames, 9u);
    EXPECT_EQ(c.rgb.crc_errors + c.depth.crc_errors + c.rgb.invalid_frames + c.depth.invalid_frames,
              0u);
    EXPECT_GE(c.pairs, 9u);
  }
}

TEST(StreamEndToEnd, BlankAndMalformedFramesAreNeverSent) {
  capture::SteadyClock clock;
  auto frames = testing::load_tum(kDesk);
  // GIVEN a stream where a driver delivered blank and truncated frames between good ones
  std::vector<capture::SourceFrame> script;
  std::int64_t t = 1;
  int good_depth = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    auto f = frames[i];
    std::visit([&](auto& x) { x.capture_timestamp_us = t++; }, f);
    if (i % 3 == 1) {
      std::visit(
          [](auto& x) {
            if constexpr (std::is_same_v<std::decay_t<decltype(x)>, capture::RgbFrame>)
              std::fill(x.rgb.begin(), x.rgb.end(), 0);
            else
              std::fill(x.depth.begin(), x.depth.end(), 0);
          },
          f);
    } else if (i % 3 == 2) {
      std::visit([](auto& x) { x.height = 240; }, f);
    } else if (std::holds_alternative<capture::DepthFrame>(f)) {
      ++good_depth;
    }
    script.push_back(std::move(f));
  }
  receiver::StreamReceiver rx(loopback_receiver(), testing::steady_now_us(), nullptr);
  stream::StreamSender rgb(sender_options(StreamKind::kRgb, rx.rgb_port(), Encoding::kRaw), &clock,
                           nullptr);
  stream::StreamSender depth(
      sender_options(StreamKind::kDepth, rx.depth_port(), Encoding::kDepthRvl), &clock, nullptr);
  ASSERT_TRUE(eventually([&] { return rgb.connected() && depth.connected(); }));
  testing::ScriptedSource source(script);
  stream::StreamerPipeline pipeline(&source, {}, std::nullopt, &rgb, &depth);
  std::uint64_t published = 0;
  while (pipeline.step()) {
    const auto c = pipeline.counters();
    if (c.rgb.published + c.depth.published > published) {
      published = c.rgb.published + c.depth.published;
      ASSERT_TRUE(eventually([&] {
        const auto rc = rx.counters();
        return rc.rgb.frames + rc.depth.frames == published;
      }));
    }
  }
  // THEN only the good frames were published and received; the rest are counted
  const auto c = pipeline.counters();
  EXPECT_EQ(c.validation.rgb_blank + c.validation.depth_blank, 6u);
  EXPECT_EQ(c.validation.malformed, 6u);
  EXPECT_EQ(c.rgb.published + c.depth.published, 6u);
  const auto rc = rx.counters();
  EXPECT_EQ(rc.depth.frames, static_cast<std::uint64_t>(good_depth));
  EXPECT_EQ(rc.rgb.frames + rc.depth.frames, 6u);
  const auto d = rx.newest_depth();
  ASSERT_TRUE(d);
  EXPECT_TRUE(
      std::any_of(d->depth.begin(), d->depth.end(), [](std::uint16_t v) { return v != 0; }));
}

TEST(StreamEndToEnd, ReconnectsAfterServerRestartsWithoutDescriptorOrMemoryGrowth) {
  capture::SteadyClock clock;
  const auto frames = testing::load_tum(kDesk);
  const auto [rgb_port, depth_port] = two_free_ports();
  stream::StreamSender rgb(sender_options(StreamKind::kRgb, rgb_port, Encoding::kRgbJpeg), &clock,
                           nullptr);
  stream::StreamSender depth(sender_options(StreamKind::kDepth, depth_port, Encoding::kDepthRvl),
                             &clock, nullptr);
  constexpr int kCycles = 25;
  int fds_after_warmup = 0;
  long rss_after_warmup_kb = 0;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    {
      // GIVEN the ground station (re)starts on the same ports
      receiver::StreamReceiver rx(loopback_receiver(rgb_port, depth_port), testing::steady_now_us(),
                                  nullptr);
      // WHEN the streamer keeps publishing
      std::size_t i = static_cast<std::size_t>(cycle) % 9;
      ASSERT_TRUE(eventually(
          [&] {
            rgb.publish(
                frames[2 * i + (std::holds_alternative<capture::RgbFrame>(frames[2 * i]) ? 0 : 1)]);
            depth.publish(
                frames[2 * i +
                       (std::holds_alternative<capture::DepthFrame>(frames[2 * i]) ? 0 : 1)]);
            return rx.counters().depth.frames > 0 && rx.counters().rgb.frames > 0;
          },
          10000))
          << "no frames after restart " << cycle;
      // THEN it reconnected and frames flow on both streams
      EXPECT_TRUE(rx.newest_depth());
    }
    if (cycle == 2) {
      fds_after_warmup = testing::open_fd_count();
      rss_after_warmup_kb = testing::rss_kb();
    }
  }
  EXPECT_TRUE(eventually([&] { return testing::open_fd_count() <= fds_after_warmup; }))
      << testing::open_fd_count() << " descriptors open, " << fds_after_warmup << " after warm-up";
  // Memory: frames are ~1.5 MB per pair; 22 leaked cycles would add > 30 MB.
  EXPECT_LT(testing::rss_kb() - rss_after_warmup_kb, 16 * 1024);
  EXPECT_GE(rgb.counters().connects, static_cast<std::uint64_t>(kCycles));
  EXPECT_GE(depth.counters().connects, static_cast<std::uint64_t>(kCycles));
}

TEST(StreamEndToEnd, ReceiverSurvivesStreamerRestarts) {
  capture::SteadyClock clock;
  const auto frames = testing::load_tum(kDesk);
  receiver::StreamReceiver rx(loopback_receiver(), testing::steady_now_us(), nullptr);
  auto depth_frame = std::get<capture::DepthFrame>(
      std::holds_alternative<capture::DepthFrame>(frames[0]) ? frames[0] : frames[1]);
  int fds_after_warmup = 0;
  for (int cycle = 0; cycle < 20; ++cycle) {
    // Each streamer run stamps its frames with its own time, so frames still in flight from the
    // previous run cannot be mistaken for this one's.
    depth_frame.capture_timestamp_us = 1'000'000 * (cycle + 1);
    stream::StreamSender depth(
        sender_options(StreamKind::kDepth, rx.depth_port(), Encoding::kDepthRvl), &clock, nullptr);
    ASSERT_TRUE(eventually([&] {
      depth.publish(depth_frame);
      const auto got = rx.newest_depth();
      return got && got->info.capture_timestamp_us == depth_frame.capture_timestamp_us;
    }));
    if (cycle == 2) fds_after_warmup = testing::open_fd_count();
  }
  EXPECT_TRUE(eventually([&] { return testing::open_fd_count() <= fds_after_warmup; }));
  EXPECT_EQ(rx.counters().depth.connections, 20u);
}

TEST(StreamEndToEnd, RefusedEncodingFallsBackToRawAndStillDeliversBitExact) {
  capture::SteadyClock clock;
  const auto frames = testing::load_tum(kDesk);
  // GIVEN a ground station that accepts only raw depth
  auto options = loopback_receiver();
  options.accepted_encodings = {Encoding::kRaw};
  receiver::StreamReceiver rx(options, testing::steady_now_us(), nullptr);
  // WHEN the streamer offers RVL
  stream::StreamSender depth(
      sender_options(StreamKind::kDepth, rx.depth_port(), Encoding::kDepthRvl), &clock, nullptr);
  auto depth_frame = std::get<capture::DepthFrame>(
      std::holds_alternative<capture::DepthFrame>(frames[0]) ? frames[0] : frames[1]);
  // THEN it is refused once, falls back to raw, and frames arrive raw and bit-exact
  ASSERT_TRUE(eventually([&] {
    depth.publish(depth_frame);
    return rx.newest_depth() != nullptr;
  }));
  EXPECT_EQ(rx.newest_depth()->info.encoding, Encoding::kRaw);
  EXPECT_EQ(rx.newest_depth()->depth, depth_frame.depth);
  EXPECT_GE(depth.counters().refused, 1u);
  EXPECT_GE(rx.counters().depth.handshakes_refused, 1u);
}

// --- authentication -------------------------------------------------------------------------

TEST(StreamAuthEndToEnd, AStreamerWithAnotherKeyIsRefusedWhileTheCraftKeepsStreaming) {
  capture::SteadyClock clock;
  const auto frames = testing::load_tum(kDesk);
  auto depth_frame = std::get<capture::DepthFrame>(
      std::holds_alternative<capture::DepthFrame>(frames[0]) ? frames[0] : frames[1]);
  receiver::StreamReceiver rx(loopback_receiver(), testing::steady_now_us(), nullptr);
  // GIVEN the craft's streamer, live and delivering frames
  stream::StreamSender craft(
      sender_options(StreamKind::kDepth, rx.depth_port(), Encoding::kDepthRvl), &clock, nullptr);
  std::int64_t stamp_us = 1'000'000;
  auto publish = [&](stream::StreamSender& s) {
    depth_frame.capture_timestamp_us = stamp_us;
    stamp_us += 33'333;
    s.publish(depth_frame);
  };
  ASSERT_TRUE(eventually([&] {
    publish(craft);
    return rx.counters().depth.frames >= 3;
  }));
  // WHEN an impostor streamer with another key connects to the same port and keeps trying
  auto impostor_options = sender_options(StreamKind::kDepth, rx.depth_port(), Encoding::kRaw);
  impostor_options.key[0] ^= 0x55;
  impostor_options.device_id = "impostor";
  stream::StreamSender impostor(impostor_options, &clock, nullptr);
  const std::uint64_t frames_before = rx.counters().depth.frames;
  ASSERT_TRUE(eventually(
      [&] {
        publish(craft);
        publish(impostor);
        return rx.counters().depth.handshakes_refused >= 3 &&
               rx.counters().depth.frames >= frames_before + 10;
      },
      10000))
      << "refused " << rx.counters().depth.handshakes_refused << ", frames "
      << rx.counters().depth.frames;
  // THEN it never becomes live, never displaces the craft, and every frame stored is the craft's
  EXPECT_FALSE(impostor.connected());
  EXPECT_EQ(impostor.counters().connects, 0u);
  EXPECT_EQ(impostor.counters().sent, 0u);
  EXPECT_EQ(rx.counters().depth.replaced, 0u);
  EXPECT_TRUE(craft.connected());
  EXPECT_EQ(craft.counters().connects, 1u);
  EXPECT_EQ(rx.newest_depth()->info.encoding, Encoding::kDepthRvl);  // the impostor offers raw
}

TEST(StreamAuthEndToEnd, AStreamerDoesNotTalkToAReceiverWithoutItsKey) {
  capture::SteadyClock clock;
  auto options = loopback_receiver();
  options.key[7] ^= 0x01;  // a ground station (or a peer posing as one) with another key
  receiver::StreamReceiver rx(options, testing::steady_now_us(), nullptr);
  stream::StreamSender sender(sender_options(StreamKind::kDepth, rx.depth_port(), Encoding::kRaw),
                              &clock, nullptr);
  capture::DepthFrame frame;
  frame.width = 640;
  frame.height = 480;
  frame.depth.assign(640 * 480, 1000);
  ASSERT_TRUE(eventually([&] {
    sender.publish(frame);
    return rx.counters().depth.handshakes_refused >= 2;
  }));
  // The receiver refuses (the streamer's mac is wrong for its key) and the streamer cannot verify
  // the refusal either: no raw fallback is tried on an unauthenticated answer.
  EXPECT_FALSE(sender.connected());
  EXPECT_EQ(sender.counters().sent, 0u);
  EXPECT_EQ(sender.counters().refused, 0u);
  EXPECT_EQ(rx.counters().depth.frames, 0u);
}

TEST(StreamAuthEndToEnd, NoKeyNoStart) {
  capture::SteadyClock clock;
  auto rx_options = loopback_receiver();
  rx_options.key = {};
  EXPECT_THROW(receiver::StreamReceiver(rx_options, testing::steady_now_us(), nullptr),
               std::runtime_error);
  auto tx_options = sender_options(StreamKind::kRgb, 5600, Encoding::kRaw);
  tx_options.key = {};
  EXPECT_THROW(stream::StreamSender(tx_options, &clock, nullptr), std::invalid_argument);
}

// --- raw-socket peers ---------------------------------------------------------------------

struct RawPeer {
  net::Waker waker;
  net::UniqueFd fd;
  protocol::StreamDecoder decoder;
  void send(const std::vector<std::uint8_t>& bytes) {
    ASSERT_EQ(net::send_all(fd.get(), bytes.data(), bytes.size(), waker, 2000), net::IoStatus::kOk);
  }
  // As a streamer: answers the receiver's challenge with `hello` signed with the test key.
  void handshake(const protocol::Handshake& hello) {
    auto challenge = receive();
    ASSERT_TRUE(challenge && std::holds_alternative<protocol::StreamChallenge>(*challenge));
    send(protocol::encode_handshake(
             protocol::testing::signed_handshake(
                 hello, std::get<protocol::StreamChallenge>(*challenge).receiver_nonce))
             .bytes);
  }
  std::optional<protocol::Message> receive(int timeout_ms = 5000) {
    std::uint8_t buffer[65536];
    while (true) {
      auto r = decoder.next();
      if (r.status == protocol::DecodeStatus::kMessage) return r.message;
      if (r.status == protocol::DecodeStatus::kError) continue;
      std::size_t got = 0;
      if (net::read_some(fd.get(), buffer, sizeof buffer, &got, waker, timeout_ms) !=
          net::IoStatus::kOk)
        return std::nullopt;
      decoder.feed(buffer, got);
    }
  }
};

protocol::Handshake depth_handshake() {
  protocol::Handshake h;
  h.stream_kind = StreamKind::kDepth;
  h.width = 640;
  h.height = 480;
  h.pixel_format = protocol::PixelFormat::kDepth16;
  h.encoding = Encoding::kRaw;
  const camera::TumCamera& fr1 = camera::kTumFr1;
  h.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, {}};
  h.depth_scale_units_per_m = camera::kTumDepthUnitsPerM;
  h.device_id = "raw-peer";
  return h;
}

TEST(StreamEndToEnd, CorruptedBytesOnTheWireAreRejectedByCrcAndCounted) {
  receiver::StreamReceiver rx(loopback_receiver(), testing::steady_now_us(), nullptr);
  RawPeer peer;
  std::string error;
  auto fd = net::connect_tcp("127.0.0.1", rx.depth_port(), 1000, peer.waker, &error);
  ASSERT_TRUE(fd) << error;
  peer.fd = std::move(*fd);
  peer.handshake(depth_handshake());
  auto ack = peer.receive();
  ASSERT_TRUE(ack && std::get<protocol::HandshakeAck>(*ack).accepted);
  const auto frames = testing::load_tum(kDesk);
  std::vector<std::uint8_t> payload(640 * 480 * 2);
  const auto& depth = std::get<capture::DepthFrame>(
      std::holds_alternative<capture::DepthFrame>(frames[0]) ? frames[0] : frames[1]);
  for (std::size_t i = 0; i < depth.depth.size(); ++i) {
    payload[2 * i] = static_cast<std::uint8_t>(depth.depth[i]);
    payload[2 * i + 1] = static_cast<std::uint8_t>(depth.depth[i] >> 8);
  }
  // WHEN 6 frames are sent and one byte of frame 2's payload and of frame 4's header is flipped
  for (std::uint32_t seq = 0; seq < 6; ++seq) {
    protocol::FrameHeader h;
    h.sequence = seq;
    h.capture_timestamp_us = 1000 + seq;
    h.width = 640;
    h.height = 480;
    h.pixel_format = protocol::PixelFormat::kDepth16;
    h.encoding = Encoding::kRaw;
    h.payload_length = static_cast<std::uint32_t>(payload.size());
    auto bytes = protocol::encode_frame(h, payload.data(), payload.size()).bytes;
    if (seq == 2) bytes[bytes.size() / 2] ^= 0x01;
    if (seq == 4) bytes[9] ^= 0x80;  // inside body_length: header CRC must catch it
    peer.send(bytes);
  }
  // THEN the receiver stores the 4 intact frames and counts 2 CRC errors
  ASSERT_TRUE(eventually([&] {
    const auto c = rx.counters().depth;
    return c.frames == 4 && c.crc_errors == 2;
  })) << "frames "
      << rx.counters().depth.frames << " crc " << rx.counters().depth.crc_errors;
  EXPECT_EQ(rx.newest_depth()->info.sequence, 5u);
  EXPECT_EQ(rx.newest_depth()->depth, depth.depth);
}

TEST(StreamEndToEnd, WrongSchemaOrStreamKindIsRefusedLoudly) {
  receiver::StreamReceiver rx(loopback_receiver(), testing::steady_now_us(), nullptr);
  struct Case {
    const char* name;
    std::uint16_t port;
    protocol::Handshake hello;
  };
  auto wrong_hash = depth_handshake();
  wrong_hash.schema_hash ^= 1;
  std::vector<Case> cases = {{"schema hash", rx.depth_port(), wrong_hash},
                             {"depth on the RGB port", rx.rgb_port(), depth_handshake()}};
  for (const auto& c : cases) {
    RawPeer peer;
    std::string error;
    auto fd = net::connect_tcp("127.0.0.1", c.port, 1000, peer.waker, &error);
    ASSERT_TRUE(fd) << error;
    peer.fd = std::move(*fd);
    peer.handshake(c.hello);
    auto ack = peer.receive();
    ASSERT_TRUE(ack.has_value()) << c.name;
    EXPECT_FALSE(std::get<protocol::HandshakeAck>(*ack).accepted) << c.name;
    EXPECT_FALSE(std::get<protocol::HandshakeAck>(*ack).reason.empty()) << c.name;
  }
  EXPECT_EQ(rx.counters().depth.handshakes_refused + rx.counters().rgb.handshakes_refused, 2u);
}

TEST(StreamEndToEnd, SlowReceiverGetsTheNewestFrameNeverABacklog) {
  capture::SteadyClock clock;
  net::UniqueFd listener = net::listen_tcp("127.0.0.1", 0);
  stream::StreamSender sender(
      sender_options(StreamKind::kDepth, net::local_port(listener), Encoding::kDepthRvl), &clock,
      nullptr);
  RawPeer rx;
  ASSERT_EQ(net::wait_readable(listener.get(), rx.waker, 5000), net::IoStatus::kOk);
  auto fd = net::accept_tcp(listener, nullptr);
  ASSERT_TRUE(fd);
  rx.fd = std::move(*fd);
  protocol::StreamChallenge challenge;
  challenge.receiver_nonce = protocol::random_stream_nonce();
  rx.send(protocol::encode_stream_challenge(challenge).bytes);
  auto hello = rx.receive();
  ASSERT_TRUE(hello && std::holds_alternative<protocol::Handshake>(*hello));
  protocol::HandshakeAck ack;
  ack.accepted = true;
  rx.send(protocol::encode_handshake_ack(
              protocol::testing::signed_ack(ack, challenge.receiver_nonce,
                                            std::get<protocol::Handshake>(*hello).sender_nonce))
              .bytes);
  ASSERT_TRUE(eventually([&] { return sender.connected(); }));
  capture::DepthFrame frame;
  frame.width = 640;
  frame.height = 480;
  frame.depth.assign(640 * 480, 1000);
  // GIVEN 50 frames captured while the receiver granted nothing
  for (int i = 0; i < 50; ++i) {
    frame.capture_timestamp_us = 1000 + i;
    sender.publish(frame);
  }
  // WHEN it grants one credit THEN it gets the newest (sequence 49), not the oldest
  protocol::FrameRequest one;
  rx.send(protocol::encode_frame_request(one).bytes);
  auto got = rx.receive();
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(std::get<protocol::Frame>(*got).image.header.sequence, 49u);
  EXPECT_EQ(std::get<protocol::Frame>(*got).image.header.capture_timestamp_us, 1049u);
  // AND with no credit nothing else arrives, however many frames are captured
  for (int i = 50; i < 60; ++i) {
    frame.capture_timestamp_us = 1000 + i;
    sender.publish(frame);
  }
  EXPECT_FALSE(rx.receive(200).has_value());
  rx.send(protocol::encode_frame_request(one).bytes);
  got = rx.receive();
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(std::get<protocol::Frame>(*got).image.header.sequence, 59u);
  // (the counters are updated just after the bytes leave, so wait for them)
  EXPECT_TRUE(eventually([&] { return sender.counters().sent == 2u; }));
  EXPECT_EQ(sender.counters().superseded, 58u);
}

}  // namespace
}  // namespace rgbdquad
