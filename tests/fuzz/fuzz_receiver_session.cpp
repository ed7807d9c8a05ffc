// libFuzzer target: the ground-station stream session (offboard/receiver receiver_session.h) fed
// hostile bytes in hostile chunks at hostile times. Byte 0 picks the port kind and whether the
// connection first completes a correctly signed handshake (so the live-state paths are reached);
// byte 1 the chunk size; the rest is what the peer sends. Properties (abort on violation):
//   - everything the session sends decodes as one of the messages a receiver may send
//     (StreamChallenge, HandshakeAck, FrameRequest), each valid per the spec;
//   - the session becomes live only through a handshake whose mac verifies under the key for
//     this connection's challenge (the fuzzer cannot forge one: 2^-64 per try);
//   - after it asked to close, it stays closed and sends nothing more.
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "rgbdquad/protocol/stream_auth_testing.hpp"
#include "rgbdquad/receiver/receiver_session.h"

namespace {

using namespace rgbdquad;

void check_sent(const std::vector<std::uint8_t>& bytes) {
  protocol::StreamDecoder d;
  d.feed(bytes);
  for (auto r = d.next(); r.status != protocol::DecodeStatus::kNeedMoreBytes; r = d.next()) {
    if (r.status != protocol::DecodeStatus::kMessage) std::abort();
    const auto type = protocol::message_type(*r.message);
    if (type != protocol::MessageType::kStreamChallenge &&
        type != protocol::MessageType::kHandshakeAck &&
        type != protocol::MessageType::kFrameRequest) {
      std::abort();
    }
  }
  if (d.buffered_bytes() != 0) std::abort();  // whole messages only
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const std::uint8_t mode = data[0];
  const std::size_t chunk = 1 + data[1] % 64;
  data += 2;
  size -= 2;
  receiver::ReceiverSessionOptions options;
  options.kind = (mode & 1) ? protocol::StreamKind::kDepth : protocol::StreamKind::kRgb;
  options.key = protocol::testing::kTestStreamKey;
  const protocol::StreamNonce nonce{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
  std::int64_t now_us = 1'000'000;
  receiver::ReceiverSession session(options, nonce, now_us);
  check_sent(session.start().send);
  if (mode & 2) {  // a correctly signed handshake first: fuzz the live connection
    protocol::Handshake h;
    h.stream_kind = options.kind;
    h.width = 64;
    h.height = 48;
    h.pixel_format = (mode & 1) ? protocol::PixelFormat::kDepth16 : protocol::PixelFormat::kRgb8;
    h.depth_scale_units_per_m = (mode & 1) ? 1000.0 : 0.0;
    const auto bytes =
        protocol::encode_handshake(protocol::testing::signed_handshake(h, nonce)).bytes;
    const auto out = session.on_bytes(now_us, bytes.data(), bytes.size());
    check_sent(out.send);
    if (!session.live()) std::abort();
  }
  bool closed = false;
  for (std::size_t off = 0; off < size; off += chunk) {
    const std::size_t n = std::min(chunk, size - off);
    now_us += 1000 * (data[off] % 8);  // time moves on by 0..7 ms per chunk
    const bool was_live = session.live();
    const auto out = session.on_bytes(now_us, data + off, n);
    if (closed && (!out.send.empty() || !out.events.empty())) std::abort();
    check_sent(out.send);
    if (!was_live && session.live() && !(mode & 2)) {
      // Only a verified mac makes it live: the accepted handshake must carry one.
      bool verified = false;
      for (const auto& e : out.events) {
        if (e.kind == receiver::ReceiverEvent::Kind::kHandshakeAccepted && e.handshake &&
            protocol::tags_equal(e.handshake->mac,
                                 protocol::handshake_tag(options.key, nonce, *e.handshake))) {
          verified = true;
        }
      }
      if (!verified) std::abort();
    }
    (void)session.on_tick(now_us);  // deadlines: const, only reported
    closed = closed || out.close.has_value();
  }
  return 0;
}
