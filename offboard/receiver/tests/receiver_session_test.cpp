// The receiver's per-connection session without sockets (receiver_session.h): replayed against the
// golden vectors of protocol/vectors (signed with the manifest's key and nonces), the
// authentication cases (wrong key, missing mac, replayed handshake) and the deadlines,
// all with time passed in.
#include "rgbdquad/receiver/receiver_session.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "rgbdquad/protocol/stream_auth_testing.hpp"

namespace rgbdquad::receiver {
namespace {

using Kind = ReceiverEvent::Kind;
const std::string kVectors = RGBD_PROTOCOL_VECTORS_DIR;

std::vector<std::uint8_t> vector_bytes(const std::string& name) {
  return protocol::testing::golden_vector_bytes(kVectors, name);
}

using VectorAuth = protocol::testing::GoldenStreamAuth;
VectorAuth vector_auth() { return protocol::testing::golden_stream_auth(kVectors); }

ReceiverSessionOptions rgb_options(const protocol::StreamKey& key) {
  ReceiverSessionOptions o;
  o.kind = protocol::StreamKind::kRgb;
  o.key = key;
  return o;
}

ReceiverOutput feed(ReceiverSession& s, std::int64_t now_us,
                    const std::vector<std::uint8_t>& bytes) {
  return s.on_bytes(now_us, bytes.data(), bytes.size());
}

bool has(const ReceiverOutput& out, Kind kind) {
  for (const auto& e : out.events) {
    if (e.kind == kind) return true;
  }
  return false;
}

std::vector<std::uint8_t> concat(std::vector<std::uint8_t> a, const std::vector<std::uint8_t>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

TEST(ReceiverSession, GoldenSignedHandshakeIsAcceptedWithTheGoldenAck) {
  const VectorAuth auth = vector_auth();
  // GIVEN a session whose challenge is the vectors' receiver nonce
  ReceiverSession s(rgb_options(auth.key), auth.receiver_nonce, 0);
  EXPECT_EQ(s.start().send, vector_bytes("stream_challenge"));
  // WHEN the signed RGB handshake arrives
  const ReceiverOutput out = feed(s, 1000, vector_bytes("handshake_rgb"));
  // THEN it is accepted, answered with exactly the golden signed ack, and 2 credits granted
  ASSERT_TRUE(has(out, Kind::kHandshakeAccepted));
  EXPECT_TRUE(s.live());
  EXPECT_FALSE(out.close);
  protocol::FrameRequest first;
  first.credits = 2;
  EXPECT_EQ(out.send, concat(vector_bytes("handshake_ack_accepted"),
                             protocol::encode_frame_request(first).bytes));
}

TEST(ReceiverSession, StreamerOfTheOlderVersionIsAnsweredInItsVersionAndItsFramesTaken) {
  const VectorAuth auth = vector_auth();
  // GIVEN a session and a streamer of the oldest decoded version (a craft not yet updated)
  ReceiverSession s(rgb_options(auth.key), auth.receiver_nonce, 0);
  EXPECT_EQ(s.start().send[4], protocol::kOldestDecodedProtocolVersion);  // it reads the challenge
  // WHEN its signed handshake (that version's schema hash) arrives
  const ReceiverOutput out = feed(s, 1000, vector_bytes("handshake_rgb_v1"));
  // THEN it is accepted and the ack and the credits are written in its version
  ASSERT_TRUE(has(out, Kind::kHandshakeAccepted)) << (out.close ? *out.close : "");
  protocol::StreamDecoder decoder;
  decoder.feed(out.send);
  int answers = 0;
  for (auto r = decoder.next(); r.status != protocol::DecodeStatus::kNeedMoreBytes;
       r = decoder.next()) {
    ASSERT_EQ(r.status, protocol::DecodeStatus::kMessage);
    EXPECT_EQ(r.version, protocol::kOldestDecodedProtocolVersion);
    ++answers;
  }
  EXPECT_EQ(answers, 2);  // HandshakeAck, FrameRequest
  // AND its frames (no accelerometer field) are taken, with no sample
  protocol::Frame f;
  f.image.header.width = 640;
  f.image.header.height = 480;
  f.image.payload.assign(640 * 480 * 3, 7);
  f.image.header.payload_length = static_cast<std::uint32_t>(f.image.payload.size());
  const ReceiverOutput frame_out =
      feed(s, 2000, protocol::encode(f, protocol::kOldestDecodedProtocolVersion).bytes);
  bool got_frame = false;
  for (const auto& e : frame_out.events) {
    if (e.kind != Kind::kFrame) continue;
    got_frame = true;
    EXPECT_FALSE(e.frame->accel.valid);
  }
  EXPECT_TRUE(got_frame);
}

TEST(ReceiverSession, UnauthenticatedHandshakesAreRefusedWithASignedReason) {
  const VectorAuth auth = vector_auth();
  protocol::StreamKey wrong_key = auth.key;
  wrong_key[3] ^= 0x10;
  protocol::StreamNonce other_nonce = auth.receiver_nonce;
  other_nonce[15] ^= 0x01;
  struct Case {
    const char* name;
    protocol::StreamKey key;
    protocol::StreamNonce nonce;
    const char* vector;
  };
  const Case cases[] = {
      {"mac with one bit flipped", auth.key, auth.receiver_nonce, "handshake_bad_mac"},
      {"no mac (a streamer without the key)", auth.key, auth.receiver_nonce, "handshake_unsigned"},
      {"receiver holds another key", wrong_key, auth.receiver_nonce, "handshake_rgb"},
      {"replayed: a handshake recorded on another connection", auth.key, other_nonce,
       "handshake_rgb"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    ReceiverSession s(rgb_options(c.key), c.nonce, 0);
    const ReceiverOutput out = feed(s, 1000, vector_bytes(c.vector));
    ASSERT_TRUE(has(out, Kind::kHandshakeRefused));
    EXPECT_FALSE(s.live());
    ASSERT_TRUE(out.close);
    EXPECT_NE(out.close->find("not authenticated"), std::string::npos) << *out.close;
    // the refusal is an ack signed for this connection: a streamer with the key can trust it
    protocol::StreamDecoder d;
    d.feed(out.send);
    const auto r = d.next();
    ASSERT_EQ(r.status, protocol::DecodeStatus::kMessage);
    const auto& ack = std::get<protocol::HandshakeAck>(*r.message);
    EXPECT_FALSE(ack.accepted);
    EXPECT_TRUE(
        protocol::tags_equal(ack.mac, protocol::ack_tag(c.key, c.nonce, auth.sender_nonce, ack)));
    EXPECT_EQ(d.next().status, protocol::DecodeStatus::kNeedMoreBytes)
        << "no credits for a refused peer";
  }
}

TEST(ReceiverSession, EveryGoldenVectorBeforeAndAfterTheHandshakeKeepsTheSessionConsistent) {
  const VectorAuth auth = vector_auth();
  std::ifstream in(kVectors + "/manifest.json");
  const auto manifest = nlohmann::json::parse(in);
  int accepted = 0;
  for (const auto& v : manifest["vectors"]) {
    const std::string name = v["name"];
    const auto bytes = vector_bytes(name);
    // As the first bytes of a connection: only the signed RGB handshakes (of this and of the
    // older decoded version) make it live.
    ReceiverSession fresh(rgb_options(auth.key), auth.receiver_nonce, 0);
    const ReceiverOutput out = feed(fresh, 10, bytes);
    if (fresh.live()) {
      ++accepted;
      EXPECT_TRUE(name == "handshake_rgb" || name == "handshake_rgb_v1") << name;
    } else if (!bytes.empty() && !out.close) {
      // incomplete input waits for more, within the deadline
      EXPECT_TRUE(out.events.empty()) << name;
      EXPECT_TRUE(fresh.on_tick(2'000'001).close) << name;
    }
    // On a live connection: never closes it, frames of another size are mismatches, every
    // frame or corrupt envelope gets a credit back.
    ReceiverSession live(rgb_options(auth.key), auth.receiver_nonce, 0);
    ASSERT_TRUE(feed(live, 10, vector_bytes("handshake_rgb")).events.size() == 1);
    const ReceiverOutput after = feed(live, 20, bytes);
    EXPECT_FALSE(after.close) << name;
    EXPECT_TRUE(live.live()) << name;
    EXPECT_FALSE(has(after, Kind::kFrame))
        << name << ": vectors' frames are 4x3, the handshake 640x480";
  }
  EXPECT_EQ(accepted, 2);
}

TEST(ReceiverSession, DeadlinesTable) {
  const protocol::StreamKey key = protocol::testing::kTestStreamKey;
  const protocol::StreamNonce nonce{1, 2, 3};
  // GIVEN a connection at t = 1 s, 2 s handshake deadline, 5 s idle timeout
  ReceiverSession s(rgb_options(key), nonce, 1'000'000);
  EXPECT_EQ(s.next_deadline_us(), 3'000'000);
  // WHEN a peer drips one byte of garbage-free magic every 100 ms THEN the deadline does not move
  const std::uint8_t magic[] = {'R', 'G', 'B', 'Q'};
  for (int i = 0; i < 4; ++i) EXPECT_FALSE(s.on_bytes(1'000'000 + 100'000 * i, &magic[i], 1).close);
  EXPECT_EQ(s.next_deadline_us(), 3'000'000);
  EXPECT_FALSE(s.on_tick(3'000'000).close);
  ASSERT_TRUE(s.on_tick(3'000'001).close);
  EXPECT_NE(s.on_tick(3'000'001).close->find("no handshake within 2000 ms"), std::string::npos);
  // AND a handshake signed correctly but arriving after the deadline is refused
  protocol::Handshake h;
  h.stream_kind = protocol::StreamKind::kRgb;
  h.width = 640;
  h.height = 480;
  ReceiverSession late(rgb_options(key), nonce, 0);
  const auto out =
      feed(late, 2'500'000,
           protocol::encode_handshake(protocol::testing::signed_handshake(h, nonce)).bytes);
  EXPECT_TRUE(has(out, Kind::kHandshakeRefused));
  // AND a live connection idle for more than 5 s is closed, activity resets the clock
  ReceiverSession live(rgb_options(key), nonce, 0);
  ASSERT_TRUE(
      has(feed(live, 100,
               protocol::encode_handshake(protocol::testing::signed_handshake(h, nonce)).bytes),
          Kind::kHandshakeAccepted));
  EXPECT_FALSE(live.on_tick(5'000'100).close);
  EXPECT_TRUE(live.on_tick(5'000'101).close);
  protocol::Frame f;
  f.image.header.width = 640;
  f.image.header.height = 480;
  f.image.payload.assign(640 * 480 * 3, 7);
  f.image.header.payload_length = static_cast<std::uint32_t>(f.image.payload.size());
  const auto frame_out = feed(live, 4'000'000, protocol::encode_frame(f).bytes);
  ASSERT_TRUE(has(frame_out, Kind::kFrame));
  EXPECT_FALSE(live.on_tick(8'000'000).close);
  // AND a second handshake on the live connection is a protocol error, not a re-negotiation
  const auto again =
      feed(live, 4'100'000,
           protocol::encode_handshake(protocol::testing::signed_handshake(h, nonce)).bytes);
  EXPECT_TRUE(has(again, Kind::kUnexpectedMessage));
  EXPECT_TRUE(again.send.empty());
}

}  // namespace
}  // namespace rgbdquad::receiver
