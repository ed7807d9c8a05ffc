// The streamer's per-connection session without sockets (sender_session.h), replayed against the
// golden vectors of protocol/vectors (signed with the manifest's key and nonces): it must answer
// the golden challenge with exactly the golden signed handshake and take exactly the golden ack;
// plus the authentication cases (an ack from a receiver without the key, a replayed ack) and the
// deadlines, with time passed in.
#include "rgbdquad/stream/sender_session.h"

#include <gtest/gtest.h>

#include "rgbdquad/protocol/stream_auth_testing.hpp"

namespace rgbdquad::stream {
namespace {

const std::string kVectors = RGBD_PROTOCOL_VECTORS_DIR;

std::vector<std::uint8_t> vector_bytes(const std::string& name) {
  return protocol::testing::golden_vector_bytes(kVectors, name);
}

protocol::Message only_message(const std::string& name) {
  protocol::StreamDecoder d;
  d.feed(vector_bytes(name));
  auto r = d.next();
  EXPECT_EQ(r.status, protocol::DecodeStatus::kMessage) << name;
  return r.message.value_or(protocol::Message{});
}

struct Golden {
  SenderSessionOptions options;
  protocol::StreamNonce sender_nonce;
  protocol::StreamNonce receiver_nonce;
};
Golden golden() {
  const protocol::testing::GoldenStreamAuth auth = protocol::testing::golden_stream_auth(kVectors);
  Golden g;
  g.options.hello = std::get<protocol::Handshake>(only_message("handshake_rgb"));
  g.options.key = auth.key;
  g.sender_nonce = auth.sender_nonce;
  g.receiver_nonce = auth.receiver_nonce;
  return g;
}

SenderOutput feed(SenderSession& s, std::int64_t now_us, const std::vector<std::uint8_t>& bytes) {
  return s.on_bytes(now_us, bytes.data(), bytes.size());
}

TEST(SenderSession, GoldenChallengeGetsTheGoldenSignedHandshakeAndTheGoldenAckIsTaken) {
  const Golden g = golden();
  SenderSession s(g.options, g.sender_nonce, 0);
  // GIVEN the golden challenge WHEN it arrives THEN the answer is byte for byte the golden
  // handshake
  const SenderOutput hello = feed(s, 1000, vector_bytes("stream_challenge"));
  EXPECT_EQ(hello.send, vector_bytes("handshake_rgb"));
  EXPECT_FALSE(hello.close);
  EXPECT_FALSE(s.live());
  // WHEN the golden signed ack and a request for 2 credits arrive THEN the connection is live
  const SenderOutput ack = feed(s, 2000, vector_bytes("handshake_ack_accepted"));
  EXPECT_TRUE(ack.accepted);
  EXPECT_TRUE(s.live());
  feed(s, 3000, vector_bytes("frame_request"));
  EXPECT_EQ(s.credits(), 2u);
  s.take_credit(4000);
  EXPECT_EQ(s.credits(), 1u);
}

TEST(SenderSession, AnswersThatAreNotSignedForThisConnectionAreNotTrusted) {
  const Golden g = golden();
  protocol::StreamNonce other_sender = g.sender_nonce;
  other_sender[0] ^= 0xFF;
  struct Case {
    const char* name;
    protocol::StreamNonce sender_nonce;
    protocol::StreamKey key;
    const char* ack_vector;
    bool refused;  // expected: an authenticated refusal
    const char* close_has;
  };
  protocol::StreamKey wrong_key = g.options.key;
  wrong_key[2] ^= 0x04;
  const Case cases[] = {
      {"signed refusal: trusted, the reason shown", g.sender_nonce, g.options.key,
       "handshake_ack_refused", true, "refused the handshake: schema hash mismatch"},
      {"ack replayed from another connection", other_sender, g.options.key,
       "handshake_ack_accepted", false, "not authenticated"},
      {"receiver without our key", g.sender_nonce, wrong_key, "handshake_ack_accepted", false,
       "not authenticated"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    SenderSessionOptions o = g.options;
    o.key = c.key;
    SenderSession s(o, c.sender_nonce, 0);
    feed(s, 10, vector_bytes("stream_challenge"));
    const SenderOutput out = feed(s, 20, vector_bytes(c.ack_vector));
    EXPECT_FALSE(out.accepted);
    EXPECT_FALSE(s.live());
    EXPECT_EQ(out.refused, c.refused);
    ASSERT_TRUE(out.close);
    EXPECT_NE(out.close->find(c.close_has), std::string::npos) << *out.close;
  }
}

TEST(SenderSession, DeadlinesTable) {
  const Golden g = golden();
  SenderSessionOptions o = g.options;
  o.handshake_timeout_us = 300'000;
  o.credit_idle_timeout_us = 3'000'000;
  // GIVEN a connection at t = 1 s WHEN the receiver drips bytes THEN the 300 ms deadline holds
  SenderSession s(o, g.sender_nonce, 1'000'000);
  const auto challenge = vector_bytes("stream_challenge");
  for (std::size_t i = 0; i < 10; ++i)
    EXPECT_FALSE(s.on_bytes(1'000'000 + 20'000 * i, &challenge[i], 1).close);
  EXPECT_FALSE(s.on_tick(1'299'999, false).close);
  ASSERT_TRUE(s.on_tick(1'300'000, false).close);
  EXPECT_NE(s.on_tick(1'300'000, false).close->find("no challenge"), std::string::npos);
  // AND with the challenge answered but no ack, the same deadline
  SenderSession waiting(o, g.sender_nonce, 0);
  feed(waiting, 10, challenge);
  ASSERT_TRUE(waiting.on_tick(300'000, false).close);
  EXPECT_NE(waiting.on_tick(300'000, false).close->find("handshake ack"), std::string::npos);
  // AND live: frames waiting without a credit for more than 3 s ends the connection, not before
  SenderSession live(o, g.sender_nonce, 0);
  feed(live, 10, challenge);
  ASSERT_TRUE(feed(live, 20, vector_bytes("handshake_ack_accepted")).accepted);
  EXPECT_FALSE(live.on_tick(3'000'020, true).close);
  EXPECT_TRUE(live.on_tick(3'000'021, true).close);
  EXPECT_FALSE(live.on_tick(9'000'000, false).close) << "nothing to send: no reason to give up";
}

}  // namespace
}  // namespace rgbdquad::stream
