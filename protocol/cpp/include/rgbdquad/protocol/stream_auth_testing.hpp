// Test helpers for stream authentication, shared by the receiver's and the streamer's tests (a
// contract helper, so neither deployable includes the other's test code). Not for production:
// kTestStreamKey is public.
#pragma once

#include <cstdint>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

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

/// The bytes of golden vector `name` (protocol/vectors/<name>.bin); empty if it is missing, which
/// the caller's comparison then reports.
inline std::vector<std::uint8_t> golden_vector_bytes(const std::string& vectors_dir,
                                                     const std::string& name) {
  std::ifstream in(vectors_dir + "/" + name + ".bin", std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// A fixed-size byte array from its lower-case hex spelling (the manifest's notation).
template <typename Array>
Array hex_array(const std::string& hex) {
  Array out{};
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = static_cast<std::uint8_t>(std::stoi(hex.substr(2 * i, 2), nullptr, 16));
  return out;
}

/// The key and nonces the golden handshake vectors are signed with (manifest.json "stream_auth").
struct GoldenStreamAuth {
  StreamKey key{};
  StreamNonce receiver_nonce{};
  StreamNonce sender_nonce{};
};

inline GoldenStreamAuth golden_stream_auth(const std::string& vectors_dir) {
  std::ifstream in(vectors_dir + "/manifest.json");
  const auto auth = nlohmann::json::parse(in)["stream_auth"];
  return {hex_array<StreamKey>(auth["key"]), hex_array<StreamNonce>(auth["receiver_nonce"]),
          hex_array<StreamNonce>(auth["sender_nonce"])};
}

}  // namespace rgbdquad::protocol::testing
