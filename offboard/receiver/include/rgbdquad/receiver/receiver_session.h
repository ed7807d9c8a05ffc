// One stream connection on the ground-station side, socket-free: bytes in,
// bytes and events out, time passed in. StreamReceiver (stream_receiver.h) is the socket shell
// around it; tests and fuzzers drive it directly.
//
// Contract (docs/protocol.md "Stream link"): start() gives the StreamChallenge to send on accept.
// The first message from the peer must be a Handshake, within handshake_deadline_us of the
// connect (absolute: dripping bytes does not extend it), whose mac verifies under the stream key
// (stream_auth.hpp) and whose fields this port accepts; the session then answers a signed
// HandshakeAck and grants credits_in_flight credits, and is live. Anything else before that
// closes the connection (refused handshakes after their signed refusal is sent). Once live, every
// Frame is checked against the handshake and granted one more credit; a corrupt envelope that
// was not garbage is granted again (it most likely carried a granted frame); a second Handshake
// or any other message is a protocol error (no sender re-handshakes on a connection: the nonce it
// would answer is spent); silence longer than idle_timeout_us closes it.
//
// Not thread-safe: one instance per connection, used by one thread.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/protocol/stream_auth.hpp"

namespace rgbdquad::receiver {

struct ReceiverSessionOptions {
  protocol::StreamKind kind = protocol::StreamKind::kRgb;
  protocol::StreamKey key{};  ///< the craft's stream key (never all zero in use)
  std::uint16_t credits_in_flight = 2;
  std::vector<protocol::Encoding> accepted_encodings;  ///< empty = any this port can carry
  /// The streamer sends its handshake as soon as the challenge arrives; 2 s from the connect is
  /// a round trip on a congested WiFi link many times over, and bounds how long a silent or
  /// dripping peer holds a candidate slot.
  std::int64_t handshake_deadline_us = 2'000'000;
  std::int64_t idle_timeout_us = 5'000'000;  ///< live connection silent this long: closed
};

struct ReceiverEvent {
  enum class Kind {
    kHandshakeAccepted,  ///< `handshake` holds it; the connection is live from now on
    kHandshakeRefused,   ///< `detail` says why (sent back in the signed ack); closing
    kFrame,              ///< `frame` matches the handshake; `wire_bytes` its envelope size
    kFrameMismatch,      ///< a Frame whose size/format/encoding differs from the handshake
    kDecodeError,        ///< `error`/`detail` from the decoder (bytes dropped)
    kUnexpectedMessage,  ///< a message not allowed at this point (`detail` names it)
  };
  Kind kind = Kind::kDecodeError;
  std::string detail;
  protocol::DecodeError error = protocol::DecodeError::kNone;
  std::optional<protocol::Handshake> handshake;
  std::optional<protocol::Frame> frame;
  std::size_t wire_bytes = 0;
};

struct ReceiverOutput {
  std::vector<std::uint8_t> send;     ///< bytes to write to the peer, in order
  std::vector<ReceiverEvent> events;  ///< in the order they happened
  std::optional<std::string> close;   ///< close the connection (after sending `send`): why
};

class ReceiverSession {
 public:
  /// `receiver_nonce`: fresh random bytes for this connection (random_stream_nonce() in the
  /// shell, fixed in tests). `connected_us`: when the connection was accepted.
  ReceiverSession(const ReceiverSessionOptions& options,
                  const protocol::StreamNonce& receiver_nonce, std::int64_t connected_us);

  /// The StreamChallenge, to send at once.
  ReceiverOutput start() const;
  /// Bytes read from the peer at `now_us`.
  ReceiverOutput on_bytes(std::int64_t now_us, const std::uint8_t* data, std::size_t size);
  /// Deadlines (handshake, idle) at `now_us`; call at least every next_deadline_us().
  ReceiverOutput on_tick(std::int64_t now_us) const;

  bool live() const { return state_ == State::kLive; }
  bool closed() const { return state_ == State::kClosed; }
  const std::optional<protocol::Handshake>& handshake() const { return handshake_; }
  /// When on_tick() next has something to do (absolute, microseconds).
  std::int64_t next_deadline_us() const;

 private:
  enum class State { kAwaitingHandshake, kLive, kClosed };
  void on_handshake(std::int64_t now_us, const protocol::Handshake& hello,
                    unsigned envelope_version, ReceiverOutput* out);
  void on_live_message(protocol::DecodeResult& r, ReceiverOutput* out);
  void grant(std::uint16_t credits, ReceiverOutput* out) const;
  void close(std::string why, ReceiverOutput* out);

  ReceiverSessionOptions options_;
  protocol::StreamNonce receiver_nonce_;
  std::int64_t connected_us_;
  std::int64_t last_activity_us_;
  State state_ = State::kAwaitingHandshake;
  protocol::StreamDecoder decoder_;
  std::optional<protocol::Handshake> handshake_;
  std::uint32_t last_sequence_ = 0xFFFFFFFFu;  ///< newest frame received (FrameRequest diagnostics)
  /// Envelope version of the peer's handshake; the ack and every FrameRequest are written in it,
  /// so a streamer of an older decoded version reads them (docs/protocol.md, versions).
  unsigned peer_version_ = protocol::kProtocolVersion;
};

/// Why `hello` cannot be served on a port of `kind` (version, schema, kind, format, encoding,
/// depth scale); empty when it can. The mac is checked separately.
std::string check_handshake(const protocol::Handshake& hello, protocol::StreamKind kind,
                            const std::vector<protocol::Encoding>& accepted);

}  // namespace rgbdquad::receiver
