// The receiver under a hostile peer: garbage on a stream port is counted but logged at
// a bounded rate (not one line per malformed envelope), and a new connection displaces the
// live streamer only once its handshake is accepted (otherwise a raw connect, even random bytes,
// would drop the real streamer), and only a handshake signed with the stream key over this
// connection's challenge is accepted (finding 6: any peer with a valid handshake was fed to SLAM).
// Loopback only.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "rgbdquad/camera/tum_cameras.hpp"
#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/receiver/log_throttle.h"
#include "rgbdquad/receiver/stream_receiver.h"

namespace rgbdquad {
namespace {

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

TEST(LogThrottle, BurstThenSuppressedThenReported) {
  receiver::LogThrottle t(3, 1'000'000);
  std::uint64_t suppressed = 99;
  // GIVEN 3 lines per second WHEN 10 arrive at once THEN 3 pass
  int passed = 0;
  for (int i = 0; i < 10; ++i) passed += t.allow(1'000'000 + i, &suppressed) ? 1 : 0;
  EXPECT_EQ(passed, 3);
  // WHEN the next window opens THEN the first line carries the 7 suppressed
  ASSERT_TRUE(t.allow(2'000'100, &suppressed));
  EXPECT_EQ(suppressed, 7u);
  ASSERT_TRUE(t.allow(2'000'200, &suppressed));
  EXPECT_EQ(suppressed, 0u);
  // AND a clock that steps back does not block logging
  EXPECT_TRUE(t.allow(5, &suppressed));
}

TEST(LogThrottle, SuppressedLinesAreReportedWhenNoFurtherLineComes) {
  receiver::LogThrottle t(2, 1'000'000);
  std::uint64_t suppressed = 0;
  EXPECT_EQ(t.unreported_due_us(), INT64_MAX);
  // GIVEN 2 lines per second WHEN 5 arrive at once and then nothing
  for (int i = 0; i < 5; ++i) (void)t.allow(1'000'000 + i, &suppressed);
  // THEN the 3 suppressed are due when the window ends, not before
  EXPECT_EQ(t.unreported_due_us(), 2'000'000);
  EXPECT_EQ(t.take_unreported(1'999'999), 0u);
  EXPECT_EQ(t.take_unreported(2'000'000), 3u);
  // AND once taken they are not reported again, neither alone nor with the next line
  EXPECT_EQ(t.take_unreported(3'000'000), 0u);
  EXPECT_EQ(t.unreported_due_us(), INT64_MAX);
  ASSERT_TRUE(t.allow(3'000'001, &suppressed));
  EXPECT_EQ(suppressed, 0u);
}

int connect_loopback(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

void send_bytes(int fd, const std::vector<std::uint8_t>& bytes) {
  ASSERT_EQ(::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(bytes.size()));
}

/// True when the peer closed `fd` within `timeout_ms` (EOF or reset); data that arrives is skipped.
bool closed_by_peer(int fd, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    char buf[4096];
    if (::recv(fd, buf, sizeof buf, 0) <= 0) return true;
  }
  return false;
}

/// The receiver's StreamChallenge, the first thing it sends on a connection; nullopt on timeout.
std::optional<protocol::StreamNonce> read_challenge(int fd, int timeout_ms = 2000) {
  protocol::StreamDecoder decoder;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    for (auto r = decoder.next(); r.status != protocol::DecodeStatus::kNeedMoreBytes;
         r = decoder.next()) {
      if (r.status != protocol::DecodeStatus::kMessage) continue;
      if (const auto* c = std::get_if<protocol::StreamChallenge>(&*r.message))
        return c->receiver_nonce;
    }
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    std::uint8_t buf[64];  // the challenge is 36 bytes and nothing follows it before the handshake
    const ssize_t got = ::recv(fd, buf, sizeof buf, 0);
    if (got <= 0) return std::nullopt;
    decoder.feed(buf, static_cast<std::size_t>(got));
  }
  return std::nullopt;
}

/// Connects, reads the challenge and sends `hello` signed with `key`; -1 on failure.
int connect_and_handshake(std::uint16_t port, const protocol::Handshake& hello,
                          const protocol::StreamKey& key = protocol::testing::kTestStreamKey) {
  const int fd = connect_loopback(port);
  if (fd < 0) return -1;
  const auto nonce = read_challenge(fd);
  if (!nonce) {
    ::close(fd);
    return -1;
  }
  const auto bytes =
      protocol::encode_handshake(protocol::testing::signed_handshake(hello, *nonce, key)).bytes;
  if (::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size())) {
    ::close(fd);
    return -1;
  }
  return fd;
}

protocol::Handshake rgb_handshake(const char* device) {
  protocol::Handshake h;
  h.stream_kind = protocol::StreamKind::kRgb;
  h.width = 640;
  h.height = 480;
  h.pixel_format = protocol::PixelFormat::kRgb8;
  h.encoding = protocol::Encoding::kRaw;
  const camera::TumCamera& fr1 = camera::kTumFr1;
  h.intrinsics = {fr1.fx_px, fr1.fy_px, fr1.cx_px, fr1.cy_px, {}};
  h.device_id = device;
  return h;
}

template <typename Pred>
bool eventually(Pred pred, int timeout_ms = 5000) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return pred();
}

/// Collects log lines; safe to read while the receiver's threads log.
class CaptureSink : public spdlog::sinks::base_sink<std::mutex> {
 public:
  std::vector<std::string> lines() {
    std::lock_guard<std::mutex> lock(mutex_);
    return lines_;
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    lines_.emplace_back(msg.payload.data(), msg.payload.size());
  }
  void flush_() override {}

 private:
  std::vector<std::string> lines_;
};

bool any_line_has(const std::vector<std::string>& lines, const char* text) {
  return std::any_of(lines.begin(), lines.end(),
                     [&](const std::string& l) { return l.find(text) != std::string::npos; });
}

TEST(ReceiverHostileInput, GarbageIsLoggedAtABoundedRate) {
  // An envelope with a broken header CRC: one decode error (and, before, one log line) each.
  auto bad = protocol::encode_frame_request(protocol::FrameRequest{}).bytes;
  ASSERT_GT(bad.size(), 16u);
  bad[12] ^= 0xFF;
  std::vector<std::uint8_t> garbage;
  constexpr int kEnvelopes = 4000;
  for (int i = 0; i < kEnvelopes; ++i) garbage.insert(garbage.end(), bad.begin(), bad.end());
  constexpr int kReconnects = 200;

  for (const bool reconnect_flood : {false, true}) {
    SCOPED_TRACE(reconnect_flood ? "200 connections, each sending garbage"
                                 : "the live connection sends garbage");
    auto sink = std::make_shared<CaptureSink>();
    auto logger = std::make_shared<spdlog::logger>("receiver-test", sink);
    receiver::ReceiverOptions o;
    o.bind_address = "127.0.0.1";
    o.rgb_port = 0;
    o.depth_port = 0;
    o.idle_timeout_ms = 60000;
    o.key = protocol::testing::kTestStreamKey;
    receiver::StreamReceiver rx(o, now_us, logger);
    std::vector<int> fds;
    auto errors = [&] { return rx.counters().rgb.crc_errors + rx.counters().rgb.protocol_errors; };
    std::uint64_t expected = 0;
    if (!reconnect_flood) {
      // GIVEN a live streamer WHEN it sends 4000 envelopes with a broken header CRC
      const int fd = connect_and_handshake(rx.rgb_port(), rgb_handshake("craft"));
      ASSERT_GE(fd, 0);
      fds.push_back(fd);
      ASSERT_TRUE(eventually([&] { return rx.connected(protocol::StreamKind::kRgb); }));
      send_bytes(fd, garbage);
      expected = kEnvelopes;
    } else {
      // GIVEN nothing WHEN 200 peers connect and each sends a broken envelope
      for (int i = 0; i < kReconnects; ++i) {
        const int fd = connect_loopback(rx.rgb_port());
        ASSERT_GE(fd, 0);
        send_bytes(fd, bad);
        fds.push_back(fd);
        // one at a time: the listen backlog is 4, and an overflowing SYN waits a 1 s retransmit
        ASSERT_TRUE(
            eventually([&] { return rx.counters().rgb.dropped_before_handshake >= fds.size(); }));
      }
      expected = kReconnects;
    }
    // THEN every one is counted (the credits re-granted per error are read and discarded here;
    // a connection evicted before it was read counts as dropped)
    EXPECT_TRUE(eventually(
        [&] {
          char buf[65536];
          for (int fd : fds) (void)::recv(fd, buf, sizeof buf, MSG_DONTWAIT);
          return reconnect_flood ? rx.counters().rgb.dropped_before_handshake >= expected
                                 : errors() >= expected;
        },
        15000))
        << errors() << " errors, " << rx.counters().rgb.dropped_before_handshake << " dropped, of "
        << expected;
    // AND the log holds a handful of lines, not one per error
    const auto lines = sink->lines();
    EXPECT_LE(lines.size(), 30u) << lines.size()
                                 << " lines, first: " << (lines.empty() ? "" : lines.front());
    EXPECT_GE(lines.size(), 1u);
    // AND WHEN the peers go away a second later THEN a line reports what was suppressed
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    for (int fd : fds) ::close(fd);
    EXPECT_TRUE(eventually([&] { return any_line_has(sink->lines(), "similar lines suppressed"); }))
        << sink->lines().back();
  }
}

TEST(ReceiverHostileInput, ANewConnectionDisplacesTheLiveStreamerOnlyAfterItsHandshake) {
  receiver::ReceiverOptions o;
  o.bind_address = "127.0.0.1";
  o.rgb_port = 0;
  o.depth_port = 0;
  o.idle_timeout_ms = 60000;  // the fake streamer sends no frames
  o.key = protocol::testing::kTestStreamKey;
  auto sink = std::make_shared<CaptureSink>();
  receiver::StreamReceiver rx(o, now_us, std::make_shared<spdlog::logger>("receiver-test", sink));
  // GIVEN a live streamer on the RGB port (handshake signed with the key, accepted); its signed
  // handshake is recorded by an eavesdropper on the WiFi
  const int live = connect_loopback(rx.rgb_port());
  ASSERT_GE(live, 0);
  const auto live_nonce = read_challenge(live);
  ASSERT_TRUE(live_nonce);
  const auto recorded = protocol::encode_handshake(protocol::testing::signed_handshake(
                                                       rgb_handshake("craft"), *live_nonce))
                            .bytes;
  send_bytes(live, recorded);
  ASSERT_TRUE(eventually([&] { return rx.connected(protocol::StreamKind::kRgb); }));

  struct Probe {
    const char* name;
    std::vector<std::uint8_t> bytes;  // sent right after the challenge; empty = silent
    bool sign = false;                // sign `hello` over this connection's challenge with `key`
    protocol::Handshake hello{};
    protocol::StreamKey key = protocol::testing::kTestStreamKey;
    const char* logged = nullptr;  // a log line that must say why
  };
  std::mt19937 rng(17);
  std::vector<std::uint8_t> random_bytes(4096);
  for (auto& b : random_bytes) b = static_cast<std::uint8_t>(rng());
  auto wrong_kind = rgb_handshake("intruder");
  wrong_kind.stream_kind =
      protocol::StreamKind::kDepth;  // a valid depth handshake, on the RGB port
  wrong_kind.pixel_format = protocol::PixelFormat::kDepth16;
  wrong_kind.depth_scale_units_per_m = 1000;
  protocol::StreamKey wrong_key = protocol::testing::kTestStreamKey;
  wrong_key[0] ^= 0x01;
  const Probe probes[] = {
      {"raw connect, silent", {}},
      {"4 KiB of random bytes", random_bytes},
      {"a frame request instead of a handshake",
       protocol::encode_frame_request(protocol::FrameRequest{}).bytes},
      {"a refused handshake (depth on the RGB port)",
       {},
       true,
       wrong_kind,
       protocol::testing::kTestStreamKey,
       "this port takes the RGB stream"},
      {"an unsigned handshake (no key)",
       protocol::encode_handshake(rgb_handshake("intruder")).bytes,
       false,
       {},
       {},
       "not authenticated"},
      {"a handshake signed with the wrong key",
       {},
       true,
       rgb_handshake("intruder"),
       wrong_key,
       "not authenticated"},
      {"the live streamer's handshake replayed", recorded, false, {}, {}, "not authenticated"},
  };
  for (const auto& probe : probes) {
    SCOPED_TRACE(probe.name);
    // WHEN a peer connects and sends the probe
    const int intruder = connect_loopback(rx.rgb_port());
    ASSERT_GE(intruder, 0);
    const auto nonce = read_challenge(intruder);
    ASSERT_TRUE(nonce) << "every connection is challenged";
    if (probe.sign) {
      const auto signed_bytes = protocol::encode_handshake(
          protocol::testing::signed_handshake(probe.hello, *nonce, probe.key));
      ASSERT_TRUE(signed_bytes.ok()) << signed_bytes.error;
      send_bytes(intruder, signed_bytes.bytes);
    } else if (!probe.bytes.empty()) {
      send_bytes(intruder, probe.bytes);
    }
    // THEN the intruder is dropped (at the latest at the 2 s handshake deadline) ...
    EXPECT_TRUE(closed_by_peer(intruder, 4000));
    ::close(intruder);
    // ... AND the live streamer was never displaced
    EXPECT_FALSE(closed_by_peer(live, 100));
    EXPECT_TRUE(rx.connected(protocol::StreamKind::kRgb));
    EXPECT_EQ(rx.counters().rgb.replaced, 0u);
    // AND the log says why
    if (probe.logged != nullptr) {
      EXPECT_TRUE(eventually([&] { return any_line_has(sink->lines(), probe.logged); }));
    }
    std::this_thread::sleep_for(
        std::chrono::milliseconds(250));  // the next probe's lines fit the 5/s log budget
  }
  EXPECT_EQ(rx.counters().rgb.dropped_before_handshake, std::size(probes));
  EXPECT_EQ(rx.counters().rgb.handshakes_refused, 4u);  // wrong kind, unsigned, wrong key, replayed

  // WHEN the streamer reconnects (a new connection with a handshake signed with the key)
  const int again = connect_and_handshake(rx.rgb_port(), rgb_handshake("craft"));
  ASSERT_GE(again, 0);
  // THEN it replaces the old connection, which is closed
  EXPECT_TRUE(eventually([&] { return rx.counters().rgb.replaced == 1; }));
  EXPECT_TRUE(closed_by_peer(live, 2000));
  EXPECT_FALSE(closed_by_peer(again, 100));
  ::close(live);
  ::close(again);
}

}  // namespace
}  // namespace rgbdquad
