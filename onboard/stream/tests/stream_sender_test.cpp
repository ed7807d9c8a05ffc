// Sender pieces without sockets: the pair-aware frame choice and the payload encoder's contract;
// and, on loopback, the handshake deadline against a receiver that drips its answer.
#include "rgbdquad/stream/stream_sender.h"

#include <gtest/gtest.h>
#include <sys/socket.h>

#include <chrono>
#include <thread>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/encodings/depth_codec.h"
#include "rgbdquad/net/socket.h"
#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/stream/payload_encoder.h"

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
  for (const auto& c : cases)
    EXPECT_EQ(choose_frame(held, c.hint, c.used_before), c.expected) << c.name;
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
  const auto back = encodings::decode_depth(encodings::DepthCodec::kRvl, payload->data(),
                                            payload->size(), 4, 2, &error);
  ASSERT_TRUE(back.has_value()) << error;
  EXPECT_EQ(*back, depth.depth);
  EXPECT_FALSE(rvl.encode(rgb, &error).has_value());
  EXPECT_NE(error.find("RGB frame given to the depth stream"), std::string::npos);
  PayloadEncoder raw_rgb(protocol::StreamKind::kRgb, protocol::Encoding::kRaw, 90, 1);
  EXPECT_EQ(*raw_rgb.encode(rgb, &error), rgb.rgb);
  EXPECT_THROW(PayloadEncoder(protocol::StreamKind::kRgb, protocol::Encoding::kDepthRvl, 90, 1),
               std::invalid_argument);
  EXPECT_EQ(depth_encoding_from_string("zstd-delta"), protocol::Encoding::kDepthZstdDelta);
  EXPECT_FALSE(rgb_encoding_from_string("rvl").has_value());
}

TEST(StreamSender, HandshakeDeadlineIsNotRestartedByADrippingReceiver) {
  // GIVEN a "receiver" that accepts and then drips one byte every 50 ms instead of an ack
  net::UniqueFd listener = net::listen_tcp("127.0.0.1", 0);
  StreamSenderOptions o;
  o.host = "127.0.0.1";
  o.port = net::local_port(listener);
  o.kind = protocol::StreamKind::kDepth;
  o.encoding = protocol::Encoding::kRaw;
  const camera::TumCamera& fr1 = camera::kTumFr1;
  o.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, {}};
  o.depth_units_per_m = camera::kTumDepthUnitsPerM;
  o.handshake_timeout_ms = 300;
  o.key = protocol::testing::kTestStreamKey;
  o.backoff_first_ms = 5;
  o.backoff_max_ms = 100;
  capture::SteadyClock clock;
  StreamSender sender(o, &clock, nullptr);
  net::Waker waker;
  ASSERT_EQ(net::wait_readable(listener.get(), waker, 5000), net::IoStatus::kOk);
  auto first = net::accept_tcp(listener, nullptr);
  ASSERT_TRUE(first);
  const auto t0 = std::chrono::steady_clock::now();
  // WHEN the drip goes on THEN the streamer gives up after its 300 ms deadline and reconnects
  // (it used to wait as long as bytes kept coming)
  bool reconnected = false;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(3)) {
    const std::uint8_t zero = 0;
    (void)::send(first->get(), &zero, 1, MSG_NOSIGNAL);
    if (net::wait_readable(listener.get(), waker, 50) == net::IoStatus::kOk) {
      reconnected = true;
      break;
    }
  }
  const auto waited_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - t0)
          .count();
  EXPECT_TRUE(reconnected) << "still waiting for the ack after " << waited_ms << " ms";
  EXPECT_LT(waited_ms, 1500);
}

}  // namespace
}  // namespace rgbdquad::stream
