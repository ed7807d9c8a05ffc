// One stream connection, socket-free: see receiver_session.h.
#include "rgbdquad/receiver/receiver_session.h"

#include <algorithm>

namespace rgbdquad::receiver {
namespace {

using protocol::DecodeStatus;
using protocol::Encoding;
using protocol::StreamKind;

void append(std::vector<std::uint8_t>& out, const protocol::EncodeResult& encoded) {
  out.insert(out.end(), encoded.bytes.begin(), encoded.bytes.end());
}

ReceiverEvent event(ReceiverEvent::Kind kind, std::string detail) {
  ReceiverEvent e;
  e.kind = kind;
  e.detail = std::move(detail);
  return e;
}

}  // namespace

std::string check_handshake(const protocol::Handshake& h, StreamKind expected,
                            const std::vector<Encoding>& accepted) {
  std::string why = protocol::handshake_incompatibility(h);
  if (!why.empty()) return why;
  if (h.stream_kind != expected) {
    return std::string("this port takes the ") + protocol::to_string(expected).data() + " stream";
  }
  const auto format =
      expected == StreamKind::kRgb ? protocol::PixelFormat::kRgb8 : protocol::PixelFormat::kDepth16;
  if (h.pixel_format != format) return "pixel format does not match the stream kind";
  if (!protocol::encoding_allows_pixel_format(h.encoding, format))
    return "encoding cannot carry this stream";
  if (!accepted.empty() &&
      std::find(accepted.begin(), accepted.end(), h.encoding) == accepted.end()) {
    return std::string("encoding ") + protocol::to_string(h.encoding).data() +
           " not accepted by this receiver";
  }
  if (expected == StreamKind::kDepth && !(h.depth_scale_units_per_m > 0))
    return "depth scale must be > 0";
  return {};
}

ReceiverSession::ReceiverSession(const ReceiverSessionOptions& options,
                                 const protocol::StreamNonce& receiver_nonce,
                                 std::int64_t connected_us)
    : options_(options),
      receiver_nonce_(receiver_nonce),
      connected_us_(connected_us),
      last_activity_us_(connected_us),
      decoder_(protocol::StreamDecoder::Options{
          protocol::max_body_bytes(static_cast<std::uint8_t>(protocol::MessageType::kFrame))}) {}

ReceiverOutput ReceiverSession::start() const {
  ReceiverOutput out;
  protocol::StreamChallenge challenge;
  challenge.receiver_nonce = receiver_nonce_;
  // Sent before the peer's version is known: in the oldest version still decoded, which every
  // streamer from then on reads (a craft running the previous streamer must still connect).
  append(out.send, protocol::encode(challenge, protocol::kOldestDecodedProtocolVersion));
  return out;
}

std::int64_t ReceiverSession::next_deadline_us() const {
  return state_ == State::kAwaitingHandshake ? connected_us_ + options_.handshake_deadline_us
                                             : last_activity_us_ + options_.idle_timeout_us;
}

ReceiverOutput ReceiverSession::on_tick(std::int64_t now_us) const {
  ReceiverOutput out;
  if (state_ == State::kAwaitingHandshake && now_us > next_deadline_us()) {
    out.close =
        "no handshake within " + std::to_string(options_.handshake_deadline_us / 1000) + " ms";
  } else if (state_ == State::kLive && now_us > next_deadline_us()) {
    out.close = "idle timeout";
  }
  return out;
}

void ReceiverSession::close(std::string why, ReceiverOutput* out) {
  state_ = State::kClosed;
  out->close = std::move(why);
}

void ReceiverSession::grant(std::uint16_t credits, ReceiverOutput* out) const {
  protocol::FrameRequest request;
  request.credits = credits;
  request.last_received_sequence = last_sequence_;
  append(out->send, protocol::encode(request, peer_version_));
}

ReceiverOutput ReceiverSession::on_bytes(std::int64_t now_us, const std::uint8_t* data,
                                         std::size_t size) {
  ReceiverOutput out;
  if (state_ == State::kClosed) return out;
  last_activity_us_ = now_us;
  decoder_.feed(data, size);
  while (state_ != State::kClosed) {
    protocol::DecodeResult r = decoder_.next();
    if (r.status == DecodeStatus::kNeedMoreBytes) break;
    if (state_ == State::kLive) {
      on_live_message(r, &out);
      continue;
    }
    // Awaiting the handshake: the first thing must be one.
    if (r.status == DecodeStatus::kError) {
      ReceiverEvent e = event(ReceiverEvent::Kind::kDecodeError, r.detail);
      e.error = r.error;
      out.events.push_back(std::move(e));
      close(std::string("bytes before a handshake: ") + protocol::to_string(r.error), &out);
      break;
    }
    const auto* hello = std::get_if<protocol::Handshake>(&*r.message);
    if (hello == nullptr) {
      out.events.push_back(
          event(ReceiverEvent::Kind::kUnexpectedMessage,
                std::string(protocol::to_string(protocol::message_type(*r.message))) +
                    " before the handshake"));
      close("first message is not a handshake", &out);
      break;
    }
    on_handshake(now_us, *hello, r.version, &out);
  }
  if (state_ == State::kAwaitingHandshake && !out.close) {
    ReceiverOutput late = on_tick(now_us);
    if (late.close) close(*late.close, &out);
  }
  return out;
}

void ReceiverSession::on_handshake(std::int64_t now_us, const protocol::Handshake& hello,
                                   unsigned envelope_version, ReceiverOutput* out) {
  // Everything this session sends from now on is in the peer's version, which it reads.
  peer_version_ = envelope_version;
  // The mac first: a peer without the key learns nothing about this port but that it is refused.
  std::string why;
  if (!protocol::tags_equal(hello.mac,
                            protocol::handshake_tag(options_.key, receiver_nonce_, hello))) {
    why = "handshake not authenticated (wrong stream key, or a replayed handshake)";
  } else if (now_us > connected_us_ + options_.handshake_deadline_us) {
    why = "handshake later than " + std::to_string(options_.handshake_deadline_us / 1000) +
          " ms after the connect";
  } else if (hello.protocol_version != envelope_version) {
    why = "handshake protocol_version " + std::to_string(hello.protocol_version) +
          " differs from its envelope's " + std::to_string(envelope_version);
  } else {
    why = check_handshake(hello, options_.kind, options_.accepted_encodings);
  }
  protocol::HandshakeAck ack;
  ack.accepted = why.empty();
  ack.reason = why;
  ack.mac = protocol::ack_tag(options_.key, receiver_nonce_, hello.sender_nonce, ack);
  append(out->send, protocol::encode(ack, peer_version_));
  if (!why.empty()) {
    out->events.push_back(event(ReceiverEvent::Kind::kHandshakeRefused, why));
    close("handshake not accepted: " + why, out);
    return;
  }
  handshake_ = hello;
  state_ = State::kLive;
  ReceiverEvent accepted = event(ReceiverEvent::Kind::kHandshakeAccepted, {});
  accepted.handshake = hello;
  out->events.push_back(std::move(accepted));
  grant(options_.credits_in_flight, out);
}

void ReceiverSession::on_live_message(protocol::DecodeResult& r, ReceiverOutput* out) {
  if (r.status == DecodeStatus::kError) {
    ReceiverEvent e = event(ReceiverEvent::Kind::kDecodeError, r.detail);
    e.error = r.error;
    out->events.push_back(std::move(e));
    // The dropped bytes were most likely a frame granted a credit: grant it again.
    if (r.error != protocol::DecodeError::kGarbageSkipped) grant(1, out);
    return;
  }
  auto* frame = std::get_if<protocol::Frame>(&*r.message);
  if (frame == nullptr) {
    out->events.push_back(
        event(ReceiverEvent::Kind::kUnexpectedMessage,
              std::string(protocol::to_string(protocol::message_type(*r.message))) +
                  " on a live stream connection"));
    return;
  }
  const auto& h = frame->image.header;
  const auto& hs = *handshake_;
  last_sequence_ = h.sequence;
  if (h.width != hs.width || h.height != hs.height || h.pixel_format != hs.pixel_format ||
      h.encoding != hs.encoding) {
    out->events.push_back(
        event(ReceiverEvent::Kind::kFrameMismatch,
              "frame " + std::to_string(h.sequence) +
                  " rejected: frame size/format/encoding differs from the handshake"));
  } else {
    ReceiverEvent e = event(ReceiverEvent::Kind::kFrame, {});
    e.wire_bytes = frame->image.payload.size() + protocol::kEnvelopeHeaderBytes +
                   protocol::kEnvelopeTrailerBytes;
    e.frame = std::move(*frame);
    out->events.push_back(std::move(e));
  }
  grant(1, out);
}

}  // namespace rgbdquad::receiver
