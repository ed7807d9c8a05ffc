// Authentication of the RGB-D stream (spec protocol.stream_auth, docs/protocol.md "Stream
// authentication"): a challenge-response under a per-craft 128-bit key that both ends read from a
// key file.
//   receiver -> sender   StreamChallenge{receiver_nonce}          (on accept)
//   sender -> receiver   Handshake{..., sender_nonce, mac}        mac = handshake_tag(...)
//   receiver -> sender   HandshakeAck{accepted, reason, mac}      mac = ack_tag(...)
// The MAC is SipHash-2-4, the control link's MAC
// (protocol/control/include/rgbd_control/siphash24.h, one implementation checked against the
// paper's vectors): no new crypto library on the craft, and a 64-bit tag that an online forger must
// guess once per TCP connection. The nonces make a recorded Handshake or HandshakeAck useless on
// any other connection. Pure functions apart from load_stream_key_file (reads one file) and
// random_stream_nonce: thread-safe.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "rgbdquad/protocol/messages.hpp"

namespace rgbdquad::protocol {

/// The shared secret of one craft (spec protocol.stream_auth.key_bytes).
using StreamKey = std::array<std::uint8_t, kStreamAuthKeyBytes>;

/// Tag of a Handshake answering `receiver_nonce`: over the label, the nonce and the Handshake's
/// body with `mac` zeroed (so the tag does not depend on the `mac` field it is written into).
StreamTag handshake_tag(const StreamKey& key, const StreamNonce& receiver_nonce,
                        const Handshake& hello);

/// Tag of a HandshakeAck on the connection whose nonces are given, over the ack's body with `mac`
/// zeroed.
StreamTag ack_tag(const StreamKey& key, const StreamNonce& receiver_nonce,
                  const StreamNonce& sender_nonce, const HandshakeAck& ack);

/// Constant-time comparison (no early exit a peer could time).
bool tags_equal(const StreamTag& a, const StreamTag& b);

/// Fresh nonce from the kernel's CSPRNG (getrandom(2)); throws std::runtime_error if it fails
/// (never on Linux >= 3.17 once the pool is initialised). The session classes take nonces as
/// parameters so tests and fuzzers stay deterministic; only the socket shells call this.
StreamNonce random_stream_nonce();

/// Parses a key written as 32 hex digits (surrounding whitespace ignored). An all-zero key is
/// refused (an unfilled template). nullopt with `error` saying why.
std::optional<StreamKey> parse_stream_key(std::string_view text, std::string* error);

/// Reads the key file at `path`: a regular file no one but its owner may read or write (mode
/// 0600 or 0400, as ssh demands of private keys), holding the key as parse_stream_key() reads it.
/// nullopt with `error` naming the path and the fix (start-up boundary).
std::optional<StreamKey> load_stream_key_file(const std::string& path, std::string* error);

}  // namespace rgbdquad::protocol
