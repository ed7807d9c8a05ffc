// Test helpers for stream authentication, shared by the receiver's and the streamer's tests (a
// contract helper, so neither deployable includes the other's test code). Not for production:
// kTestStreamKey is public.
#pragma once

#include "rgbdquad/protocol/stream_auth.hpp"

namespace rgbdquad::protocol::testing {

/// The key every test peer and test receiver/sender uses (arbitrary, non-zero).
inline constexpr StreamKey kTestStreamKey = {0x7a, 0x11, 0x5c, 0x02, 0xe9, 0x48, 0x33, 0xb0,
                                             0x6d, 0x91, 0x0f, 0xc4, 0x25, 0x8e, 0x57, 0xda};

/// `hello` signed as an answer to `receiver_nonce` under `key`.
inline Handshake signed_handshake(Handshake hello, const StreamNonce& receiver_nonce,
                                  const StreamKey& key = kTestStreamKey) {
  hello.mac = handshake_tag(key, receiver_nonce, hello);
  return hello;
}

/// `ack` signed for the connection with these nonces under `key`.
inline HandshakeAck signed_ack(HandshakeAck ack, const StreamNonce& receiver_nonce,
                               const StreamNonce& sender_nonce,
                               const StreamKey& key = kTestStreamKey) {
  ack.mac = ack_tag(key, receiver_nonce, sender_nonce, ack);
  return ack;
}

}  // namespace rgbdquad::protocol::testing
