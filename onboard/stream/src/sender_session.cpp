// One stream connection on the streamer's side, socket-free: see sender_session.h.
#include "rgbdquad/stream/sender_session.h"

#include <algorithm>

namespace rgbdquad::stream {
namespace {
// Credits banked at most: the protocol's per-request maximum (kMaxCreditsPerRequest = 8).
constexpr std::uint32_t kMaxBankedCredits = protocol::kMaxCreditsPerRequest;
}  // namespace

SenderSession::SenderSession(SenderSessionOptions options,
                             const protocol::StreamNonce& sender_nonce, std::int64_t connected_us)
    : options_(std::move(options)), connected_us_(connected_us), last_request_us_(connected_us) {
  options_.hello.sender_nonce = sender_nonce;
  // Only StreamChallenge, HandshakeAck and FrameRequest are expected: a few hundred bytes at
  // most, so a hostile length never makes the streamer buffer a megabyte.
  decoder_ = protocol::StreamDecoder(protocol::StreamDecoder::Options{
      protocol::max_body_bytes(static_cast<std::uint8_t>(protocol::MessageType::kHandshakeAck))});
}

std::int64_t SenderSession::next_deadline_us() const {
  if (state_ == State::kLive) return last_request_us_ + options_.credit_idle_timeout_us;
  return connected_us_ + options_.handshake_timeout_us;
}

SenderOutput SenderSession::on_tick(std::int64_t now_us, bool frames_waiting) const {
  SenderOutput out;
  const std::int64_t timeout_ms = options_.handshake_timeout_us / 1000;
  if (state_ == State::kAwaitingChallenge && now_us >= next_deadline_us()) {
    out.close = "no challenge from the receiver within " + std::to_string(timeout_ms) + " ms";
  } else if (state_ == State::kAwaitingAck && now_us >= next_deadline_us()) {
    out.close = "waiting for handshake ack: timeout (" + std::to_string(timeout_ms) + " ms)";
  } else if (state_ == State::kLive && credits_ == 0 && frames_waiting &&
             now_us > next_deadline_us()) {
    out.close =
        "no frame request for " + std::to_string(options_.credit_idle_timeout_us / 1000) + " ms";
  }
  return out;
}

void SenderSession::take_credit(std::int64_t now_us) {
  if (credits_ > 0) --credits_;
  last_request_us_ = now_us;
}

SenderOutput SenderSession::on_bytes(std::int64_t now_us, const std::uint8_t* data,
                                     std::size_t size) {
  SenderOutput out;
  if (state_ == State::kClosed) return out;
  decoder_.feed(data, size);
  while (state_ != State::kClosed) {
    const protocol::DecodeResult r = decoder_.next();
    if (r.status == protocol::DecodeStatus::kNeedMoreBytes) break;
    if (r.status != protocol::DecodeStatus::kMessage)
      continue;  // damaged bytes: ignored, deadlines bound them
    on_message(now_us, *r.message, &out);
  }
  if (state_ != State::kClosed && state_ != State::kLive && !out.close) {
    SenderOutput late = on_tick(now_us, false);
    if (late.close) {
      state_ = State::kClosed;
      out.close = late.close;
    }
  }
  return out;
}

void SenderSession::on_message(std::int64_t now_us, const protocol::Message& m, SenderOutput* out) {
  auto close = [&](std::string why) {
    state_ = State::kClosed;
    out->close = std::move(why);
  };
  switch (state_) {
    case State::kAwaitingChallenge: {
      const auto* challenge = std::get_if<protocol::StreamChallenge>(&m);
      if (challenge == nullptr) {
        close(std::string("receiver sent ") +
              protocol::to_string(protocol::message_type(m)).data() +
              " instead of a challenge (a receiver from before stream authentication?)");
        return;
      }
      receiver_nonce_ = challenge->receiver_nonce;
      protocol::Handshake& hello = options_.hello;
      hello.mac = protocol::handshake_tag(options_.key, receiver_nonce_, hello);
      const protocol::EncodeResult bytes = protocol::encode_handshake(hello);
      if (!bytes.ok()) {
        close("handshake invalid: " + bytes.error);
        return;
      }
      out->send.insert(out->send.end(), bytes.bytes.begin(), bytes.bytes.end());
      state_ = State::kAwaitingAck;
      return;
    }
    case State::kAwaitingAck: {
      const auto* ack = std::get_if<protocol::HandshakeAck>(&m);
      if (ack == nullptr) return;  // as before: only the ack counts here
      const bool authentic = protocol::tags_equal(
          ack->mac,
          protocol::ack_tag(options_.key, receiver_nonce_, options_.hello.sender_nonce, *ack));
      if (!authentic) {
        close(std::string(
                  "the receiver's answer is not authenticated (wrong stream key on one side?)") +
              (ack->accepted ? "" : "; it said: " + ack->reason));
        return;
      }
      if (!ack->accepted) {
        out->refused = true;
        close("receiver refused the handshake: " + ack->reason);
        return;
      }
      state_ = State::kLive;
      last_request_us_ = now_us;
      out->accepted = true;
      return;
    }
    case State::kLive:
      if (const auto* request = std::get_if<protocol::FrameRequest>(&m)) {
        credits_ = std::min<std::uint32_t>(kMaxBankedCredits, credits_ + request->credits);
        last_request_us_ = now_us;
      }
      return;
    case State::kClosed:
      return;
  }
}

}  // namespace rgbdquad::stream
