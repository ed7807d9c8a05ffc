// libFuzzer target: the streamer's stream session (onboard/stream sender_session.h) fed what a
// hostile "receiver" sends, in hostile chunks at hostile times. Byte 0: whether a genuine
// challenge and signed ack come first (so the live, credit-counting paths are reached); byte 1:
// the chunk size. Properties (abort on violation): the session sends only valid Handshakes (at
// most one per connection); it becomes live only on an ack whose mac verifies; credits never
// exceed the protocol's maximum; after close nothing more is sent.
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/stream/sender_session.h"

namespace {

using namespace rgbdquad;

int handshakes_in(const std::vector<std::uint8_t>& bytes) {
  protocol::StreamDecoder d;
  d.feed(bytes);
  int n = 0;
  for (auto r = d.next(); r.status != protocol::DecodeStatus::kNeedMoreBytes; r = d.next()) {
    if (r.status != protocol::DecodeStatus::kMessage) std::abort();
    if (protocol::message_type(*r.message) != protocol::MessageType::kHandshake) std::abort();
    ++n;
  }
  if (d.buffered_bytes() != 0) std::abort();
  return n;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const std::uint8_t mode = data[0];
  const std::size_t chunk = 1 + data[1] % 64;
  data += 2;
  size -= 2;
  stream::SenderSessionOptions options;
  options.hello.stream_kind = protocol::StreamKind::kDepth;
  options.hello.width = 64;
  options.hello.height = 48;
  options.hello.pixel_format = protocol::PixelFormat::kDepth16;
  options.hello.depth_scale_units_per_m = 1000.0;
  options.key = protocol::testing::kTestStreamKey;
  const protocol::StreamNonce sender_nonce{9, 9, 9, 9, 9, 9, 9, 9, 1, 2, 3, 4, 5, 6, 7, 8};
  std::int64_t now_us = 5'000'000;
  stream::SenderSession session(options, sender_nonce, now_us);
  int handshakes = 0;
  if (mode & 1) {
    protocol::StreamChallenge c;
    c.receiver_nonce = {4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4};
    auto bytes = protocol::encode_stream_challenge(c).bytes;
    handshakes += handshakes_in(session.on_bytes(now_us, bytes.data(), bytes.size()).send);
    protocol::HandshakeAck ack;
    ack.accepted = true;
    bytes = protocol::encode_handshake_ack(
                protocol::testing::signed_ack(ack, c.receiver_nonce, sender_nonce))
                .bytes;
    if (!session.on_bytes(now_us, bytes.data(), bytes.size()).accepted || !session.live())
      std::abort();
  }
  bool closed = false;
  for (std::size_t off = 0; off < size; off += chunk) {
    const std::size_t n = std::min(chunk, size - off);
    now_us += 1000 * (data[off] % 8);
    const bool was_live = session.live();
    const auto out = session.on_bytes(now_us, data + off, n);
    if (closed && (!out.send.empty() || out.accepted)) std::abort();
    handshakes += handshakes_in(out.send);
    if (handshakes > 1) std::abort();
    if (!was_live && session.live() && !(mode & 1)) std::abort();  // a forged ack was taken (2^-64)
    if (session.credits() > protocol::kMaxCreditsPerRequest) std::abort();
    if ((data[off] & 0x80) && session.credits() > 0) session.take_credit(now_us);
    (void)session.on_tick(now_us, true);  // deadlines: const, only reported
    closed = closed || out.close.has_value();
  }
  return 0;
}
