// One stream connection on the streamer's side, socket-free: bytes in, bytes
// and a state out, time passed in. StreamSender (stream_sender.h) is the socket shell around it,
// which also picks the frames to send.
//
// Contract (docs/protocol.md "Stream link"): the receiver opens with a StreamChallenge; the
// session answers with the Handshake, signed with the stream key over that challenge and a fresh
// sender nonce (protocol/stream_auth.hpp); it then needs a HandshakeAck whose mac verifies (so a
// receiver without the key cannot pose as the ground station). Challenge and ack together must
// arrive within handshake_timeout_us of the connect (absolute: a dripping receiver does not
// extend it). Once accepted, every FrameRequest adds credits (banked up to the protocol's
// per-request maximum); the shell sends one frame per credit (take_credit()). With frames
// waiting and no credit for credit_idle_timeout_us, the receiver is considered gone.
//
// Not thread-safe: one instance per connection, used by the connection thread.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/protocol/stream_auth.hpp"

namespace rgbdquad::stream {

struct SenderSessionOptions {
  protocol::Handshake hello;  ///< what to announce; sender_nonce and mac are filled in here
  protocol::StreamKey key{};
  std::int64_t handshake_timeout_us = 2'000'000;
  std::int64_t credit_idle_timeout_us = 3'000'000;
};

struct SenderOutput {
  std::vector<std::uint8_t> send;    ///< bytes to write to the receiver, in order
  std::optional<std::string> close;  ///< end the connection: why (for the log)
  /// The receiver refused the handshake with a signed ack (so the reason is its own, e.g. an
  /// encoding it does not take: the shell may offer raw next). False for unauthenticated answers.
  bool refused = false;
  bool accepted = false;  ///< the handshake was accepted by this call (the connection is live)
};

class SenderSession {
 public:
  /// `sender_nonce`: fresh random bytes for this connection (random_stream_nonce() in the shell).
  SenderSession(SenderSessionOptions options, const protocol::StreamNonce& sender_nonce,
                std::int64_t connected_us);

  SenderOutput on_bytes(std::int64_t now_us, const std::uint8_t* data, std::size_t size);
  /// Deadlines at `now_us`; `frames_waiting`: the shell holds a frame it could send.
  SenderOutput on_tick(std::int64_t now_us, bool frames_waiting) const;

  bool live() const { return state_ == State::kLive; }
  std::uint32_t credits() const { return credits_; }
  /// One frame was sent at `now_us` against a credit (requires credits() > 0).
  void take_credit(std::int64_t now_us);
  /// When on_tick() next may have something to do (absolute, microseconds).
  std::int64_t next_deadline_us() const;

 private:
  enum class State { kAwaitingChallenge, kAwaitingAck, kLive, kClosed };
  void on_message(std::int64_t now_us, const protocol::Message& m, SenderOutput* out);

  SenderSessionOptions options_;
  std::int64_t connected_us_;
  State state_ = State::kAwaitingChallenge;
  protocol::StreamDecoder decoder_;
  protocol::StreamNonce receiver_nonce_{};
  std::uint32_t credits_ = 0;
  std::int64_t last_request_us_ = 0;
};

}  // namespace rgbdquad::stream
