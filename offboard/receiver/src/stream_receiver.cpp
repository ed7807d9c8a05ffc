// Ground-station receiver of the RGB and depth streams.
#include "rgbdquad/receiver/stream_receiver.h"

#include <poll.h>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "rgbdquad/encodings/depth_codec.h"
#include "rgbdquad/encodings/jpeg_codec.h"
#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/receiver/log_throttle.h"

namespace rgbdquad::receiver {
namespace {

using protocol::Encoding;
using protocol::StreamKind;

// Socket read size: 256 KiB moves a raw RGB frame (921 KB) in four reads.
constexpr std::size_t kReadChunkBytes = 256 * 1024;
// A FrameRequest must leave within 1 s or the link is considered dead.
constexpr int kSendTimeoutMs = 1000;
// A new connection is a candidate until its handshake is accepted: only then may it replace the
// live streamer (a raw connect, or random bytes, used to drop the real streamer at once). The
// streamer sends its handshake as soon as it connects; 2 s is an absolute deadline from the
// connect (not restarted per byte, so a dripping peer cannot hold a slot).
constexpr std::int64_t kHandshakeDeadlineUs = 2'000'000;
// Candidates at once: the streamer reconnecting plus a few stray peers; more evicts the oldest.
constexpr std::size_t kMaxCandidates = 4;
// Poll slice while candidates wait, so their deadlines fire on time.
constexpr int kCandidatePollMs = 100;
// A failed accept (EMFILE at the descriptor limit) leaves the connection in the backlog, so the
// listener stays readable: it is left out of poll() this long instead of spinning a core.
constexpr std::int64_t kAcceptBackoffUs = 100'000;

struct Session {
  net::UniqueFd fd;
  std::string peer;
  protocol::StreamDecoder decoder{protocol::StreamDecoder::Options{
      protocol::max_body_bytes(static_cast<std::uint8_t>(protocol::MessageType::kFrame))}};
  std::optional<protocol::Handshake> handshake;
  std::int64_t last_activity_us = 0;
  std::int64_t connected_us = 0;
};

std::string check_handshake(const protocol::Handshake& h, StreamKind expected,
                            const std::vector<Encoding>& accepted) {
  std::string why = protocol::handshake_incompatibility(h);
  if (!why.empty()) return why;
  if (h.stream_kind != expected) {
    return std::string("this port takes the ") + protocol::to_string(expected).data() + " stream";
  }
  const auto format = expected == StreamKind::kRgb ? protocol::PixelFormat::kRgb8 : protocol::PixelFormat::kDepth16;
  if (h.pixel_format != format) return "pixel format does not match the stream kind";
  if (!protocol::encoding_allows_pixel_format(h.encoding, format)) return "encoding cannot carry this stream";
  if (!accepted.empty() && std::find(accepted.begin(), accepted.end(), h.encoding) == accepted.end()) {
    return std::string("encoding ") + protocol::to_string(h.encoding).data() + " not accepted by this receiver";
  }
  if (expected == StreamKind::kDepth && !(h.depth_scale_units_per_m > 0)) return "depth scale must be > 0";
  return {};
}

}  // namespace


bool ReceiverOptions::is_valid(std::string* error) const {
  if (credits_in_flight < 1 || credits_in_flight > protocol::kMaxCreditsPerRequest) *error = "credits_in_flight must be 1..8";
  else if (max_pair_gap_us < 0) *error = "max_pair_gap_us must be >= 0";
  else if (history_frames < 1 || history_frames > 64) *error = "history_frames must be 1..64";
  else if (idle_timeout_ms < 100) *error = "idle_timeout_ms must be >= 100";
  else if (rgb_port != 0 && rgb_port == depth_port) *error = "RGB and depth ports must differ";
  else return true;
  return false;
}

StreamReceiver::StreamReceiver(const ReceiverOptions& options, std::function<std::int64_t()> now_us,
                               std::shared_ptr<spdlog::logger> logger)
    : options_(options), now_us_(std::move(now_us)), log_(std::move(logger)) {
  std::string why;
  if (!options_.is_valid(&why)) throw std::runtime_error("receiver: " + why);
  if (!log_) log_ = std::make_shared<spdlog::logger>("null", std::make_shared<spdlog::sinks::null_sink_mt>());
  listeners_[0] = net::listen_tcp(options_.bind_address, options_.rgb_port);
  listeners_[1] = net::listen_tcp(options_.bind_address, options_.depth_port);
  for (int i = 0; i < 2; ++i) {
    ports_[i] = net::local_port(listeners_[i]);
    connected_[i] = false;
  }
  for (int i = 0; i < 2; ++i) threads_[i] = std::thread([this, i] { serve(i); });
}

StreamReceiver::~StreamReceiver() {
  stop_waker_.wake();
  for (auto& t : threads_) t.join();
}

bool StreamReceiver::connected(StreamKind kind) const {
  return connected_[kind == StreamKind::kRgb ? 0 : 1];
}

void StreamReceiver::serve(int index) {
  const StreamKind kind = index == 0 ? StreamKind::kRgb : StreamKind::kDepth;
  const char* name = index == 0 ? "rgb" : "depth";
  auto counter = [this, index]() -> ChannelCounters& { return index == 0 ? counters_.rgb : counters_.depth; };
  std::optional<Session> session;  // the live streamer (its handshake accepted)
  std::vector<Session> candidates;  // connected, handshake not (yet) accepted
  bool drain_pending = false;       // a promoted candidate may hold buffered messages
  std::int64_t accept_paused_until_us = 0;
  std::vector<std::uint8_t> buffer(kReadChunkBytes);
  encodings::JpegDecoder jpeg;
  // Every line a peer's input can cause goes through one throttle per stream: garbage used to
  // give one line per malformed envelope (every 16 bytes).
  LogThrottle throttle;
  auto peer_log = [&](spdlog::level::level_enum level, const std::string& line) {
    std::uint64_t suppressed = 0;
    if (!throttle.allow(now_us_(), &suppressed)) return;
    if (suppressed > 0) {
      log_->log(level, "{} (and {} similar lines suppressed)", line, suppressed);
    } else {
      log_->log(level, "{}", line);
    }
  };

  auto drop = [&](const char* why) {
    if (!session) return;
    peer_log(spdlog::level::warn, fmt::format("{} stream: {} from {}", name, why, session->peer));
    session.reset();
    connected_[index] = false;
    std::lock_guard<std::mutex> lock(mutex_);
    ++counter().disconnects;
  };
  auto drop_candidate = [&](std::size_t i, const std::string& why) {
    peer_log(spdlog::level::warn, fmt::format("{} stream: {} from {} (not a live connection: nothing displaced)",
                                              name, why, candidates[i].peer));
    candidates.erase(candidates.begin() + static_cast<std::ptrdiff_t>(i));
    std::lock_guard<std::mutex> lock(mutex_);
    ++counter().dropped_before_handshake;
  };
  // Sends the ack; an accepted handshake makes `peer` the live session (replacing the previous
  // one). Returns false when the connection is to be dropped.
  auto answer_handshake = [&](Session& peer, const protocol::Handshake& hello) {
    const std::string why = check_handshake(hello, kind, options_.accepted_encodings);
    protocol::HandshakeAck ack;
    ack.accepted = why.empty();
    ack.reason = why;
    if (!why.empty()) {
      peer_log(spdlog::level::err, fmt::format("{} stream: refused handshake from {}: {}", name, peer.peer, why));
      std::lock_guard<std::mutex> lock(mutex_);
      ++counter().handshakes_refused;
    }
    const auto bytes = protocol::encode_handshake_ack(ack);
    const bool sent = net::send_all(peer.fd.get(), bytes.bytes.data(), bytes.bytes.size(), stop_waker_,
                                    kSendTimeoutMs) == net::IoStatus::kOk;
    if (!why.empty() || !sent) return false;
    peer.handshake = hello;
    if (kind == StreamKind::kRgb) {
      std::lock_guard<std::mutex> lock(mutex_);
      rgb_intrinsics_ = hello.intrinsics;
    }
    log_->info("{} stream: {} connected ({}x{}, {}, device '{}')", name, peer.peer, hello.width, hello.height,
               protocol::to_string(hello.encoding).data(), hello.device_id);
    return true;
  };
  auto grant = [&](std::uint16_t credits) {
    protocol::FrameRequest request;
    request.credits = credits;
    const auto bytes = protocol::encode_frame_request(request);
    return net::send_all(session->fd.get(), bytes.bytes.data(), bytes.bytes.size(), stop_waker_,
                         kSendTimeoutMs) == net::IoStatus::kOk;
  };

  while (true) {
    const bool accept_paused = now_us_() < accept_paused_until_us;
    std::vector<pollfd> fds = {{stop_waker_.fd(), POLLIN, 0},
                               {accept_paused ? -1 : listeners_[index].get(), POLLIN, 0},
                               {session ? session->fd.get() : -1, POLLIN, 0}};
    for (const Session& c : candidates) fds.push_back({c.fd.get(), POLLIN, 0});
    int timeout_ms = options_.idle_timeout_ms;
    if (!candidates.empty() || accept_paused) timeout_ms = std::min(timeout_ms, kCandidatePollMs);
    if (drain_pending) timeout_ms = 0;
    const int n = poll(fds.data(), fds.size(), timeout_ms);
    if (n < 0 && errno != EINTR) break;
    if (fds[0].revents & POLLIN) break;

    // Candidates: the first message must be an acceptable handshake, within the deadline.
    bool promoted = false;
    for (std::size_t i = candidates.size(); i-- > 0;) {
      Session& c = candidates[i];
      if (!(fds[3 + i].revents & (POLLIN | POLLHUP | POLLERR))) {
        if (now_us_() - c.connected_us > kHandshakeDeadlineUs) drop_candidate(i, "no handshake within 2 s");
        continue;
      }
      std::size_t got = 0;
      const net::IoStatus s = net::read_some(c.fd.get(), buffer.data(), buffer.size(), &got, stop_waker_, 0);
      if (s == net::IoStatus::kTimeout) continue;
      if (s != net::IoStatus::kOk) {
        drop_candidate(i, std::string("closed before its handshake: ") + net::to_string(s));
        continue;
      }
      c.decoder.feed(buffer.data(), got);
      const auto r = c.decoder.next();
      if (r.status == protocol::DecodeStatus::kNeedMoreBytes) {
        if (now_us_() - c.connected_us > kHandshakeDeadlineUs) drop_candidate(i, "no handshake within 2 s");
        continue;
      }
      if (r.status == protocol::DecodeStatus::kError) {
        {
          std::lock_guard<std::mutex> lock(mutex_);
          ++counter().protocol_errors;
        }
        drop_candidate(i, std::string("bytes before a handshake: ") + protocol::to_string(r.error));
        continue;
      }
      const auto* hello = std::get_if<protocol::Handshake>(&*r.message);
      if (hello == nullptr) {
        {
          std::lock_guard<std::mutex> lock(mutex_);
          ++counter().protocol_errors;
        }
        drop_candidate(i, "first message is not a handshake");
        continue;
      }
      if (!answer_handshake(c, *hello)) {
        drop_candidate(i, "handshake not accepted");
        continue;
      }
      // Authenticated as far as this protocol can (valid handshake): now it replaces the live one.
      Session next = std::move(c);
      candidates.erase(candidates.begin() + static_cast<std::ptrdiff_t>(i));
      if (session) {
        peer_log(spdlog::level::warn, fmt::format("{} stream: {} replaced by {} (its handshake accepted)", name,
                                                  session->peer, next.peer));
        std::lock_guard<std::mutex> lock(mutex_);
        ++counter().replaced;
        ++counter().disconnects;
      }
      session = std::move(next);
      session->last_activity_us = now_us_();
      connected_[index] = true;
      if (!grant(options_.credits_in_flight)) {
        drop("connection closed");
        continue;
      }
      promoted = true;
      drain_pending = true;
      break;  // fds no longer match the candidates: poll again
    }
    if (promoted) continue;

    if (fds[1].revents & POLLIN) {
      std::string peer;
      if (auto fd = net::accept_tcp(listeners_[index], &peer)) {
        if (candidates.size() >= kMaxCandidates) drop_candidate(0, "too many connections awaiting a handshake");
        Session c;
        c.fd = std::move(*fd);
        c.peer = peer;
        c.connected_us = c.last_activity_us = now_us_();
        candidates.push_back(std::move(c));
        std::lock_guard<std::mutex> lock(mutex_);
        ++counter().connections;
      } else {
        accept_paused_until_us = now_us_() + kAcceptBackoffUs;
      }
      continue;  // poll again with the new socket
    }
    if (!session) {
      drain_pending = false;
      continue;
    }
    const bool readable = fds[2].revents & (POLLIN | POLLHUP | POLLERR);
    if (!readable && !drain_pending) {
      if (now_us_() - session->last_activity_us > std::int64_t{options_.idle_timeout_ms} * 1000) {
        drop("idle timeout");
      }
      continue;
    }
    drain_pending = false;
    if (readable) {
      std::size_t got = 0;
      const net::IoStatus s = net::read_some(session->fd.get(), buffer.data(), buffer.size(), &got, stop_waker_, 0);
      if (s == net::IoStatus::kTimeout) continue;
      if (s != net::IoStatus::kOk) {
        drop(net::to_string(s));
        continue;
      }
      session->last_activity_us = now_us_();
      session->decoder.feed(buffer.data(), got);
    }
    bool alive = true;
    for (auto r = session->decoder.next(); alive && r.status != protocol::DecodeStatus::kNeedMoreBytes;
         r = session->decoder.next()) {
      if (r.status == protocol::DecodeStatus::kError) {
        const bool crc = r.error == protocol::DecodeError::kBadBodyCrc || r.error == protocol::DecodeError::kBadHeaderCrc;
        {
          std::lock_guard<std::mutex> lock(mutex_);
          ++(crc ? counter().crc_errors : counter().protocol_errors);
        }
        peer_log(spdlog::level::warn, fmt::format("{} stream: dropped bytes from {}: {} ({})", name, session->peer,
                                                  protocol::to_string(r.error), r.detail));
        // The dropped bytes were most likely a frame we granted a credit for: grant it again.
        if (session->handshake && r.error != protocol::DecodeError::kGarbageSkipped) alive = grant(1);
        continue;
      }
      if (const auto* hello = std::get_if<protocol::Handshake>(&*r.message)) {
        // A new handshake on the live connection (the streamer changed its encoding).
        alive = answer_handshake(*session, *hello);
        if (!alive) continue;
        connected_[index] = true;
        alive = grant(options_.credits_in_flight);
        continue;
      }
      const auto* frame = std::get_if<protocol::Frame>(&*r.message);
      if (frame == nullptr || !session->handshake) {
        std::lock_guard<std::mutex> lock(mutex_);
        ++counter().protocol_errors;  // wrong message for this link, or a frame before the handshake
        continue;
      }
      const auto& h = frame->image.header;
      const auto& hs = *session->handshake;
      FrameInfo info;
      info.sequence = h.sequence;
      info.capture_timestamp_us = static_cast<std::int64_t>(h.capture_timestamp_us);
      info.send_timestamp_us = static_cast<std::int64_t>(h.send_timestamp_us);
      info.receive_timestamp_us = now_us_();
      info.encoding = h.encoding;
      info.width = h.width;
      info.height = h.height;
      info.wire_bytes = frame->image.payload.size() + 16 + 4;  // payload + envelope header/trailer
      std::string error;
      bool ok = h.width == hs.width && h.height == hs.height && h.pixel_format == hs.pixel_format &&
                h.encoding == hs.encoding;
      if (!ok) error = "frame size/format/encoding differs from the handshake";
      const auto& payload = frame->image.payload;
      const std::int64_t start_us = now_us_();
      if (ok && kind == StreamKind::kRgb) {
        auto out = std::make_shared<ReceivedRgb>();
        out->info = info;
        if (h.encoding == Encoding::kRgbJpeg) {
          auto pixels = jpeg.decode(payload.data(), payload.size(), h.width, h.height, &error);
          ok = pixels.has_value();
          if (ok) out->rgb = std::move(*pixels);
        } else {
          out->rgb = payload;  // RAW: the protocol decoder checked the length
        }
        out->info.decode_us = now_us_() - start_us;
        if (ok) store_rgb(std::move(out));
      } else if (ok) {
        const encodings::DepthCodec codec = h.encoding == Encoding::kDepthRvl ? encodings::DepthCodec::kRvl
                                            : h.encoding == Encoding::kDepthZstdDelta ? encodings::DepthCodec::kZstdDelta
                                                                                      : encodings::DepthCodec::kRaw;
        auto pixels = encodings::decode_depth(codec, payload.data(), payload.size(), h.width, h.height, &error);
        ok = pixels.has_value();
        if (ok) {
          auto out = std::make_shared<ReceivedDepth>();
          out->info = info;
          out->info.decode_us = now_us_() - start_us;
          out->units_per_m = hs.depth_scale_units_per_m;
          out->depth = std::move(*pixels);
          store_depth(std::move(out));
        }
      }
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (ok) {
          ++counter().frames;
          counter().wire_bytes += info.wire_bytes;
          counter().decode_us_total += now_us_() - start_us;
        } else {
          ++counter().invalid_frames;
        }
      }
      if (!ok) peer_log(spdlog::level::warn, fmt::format("{} stream: frame {} rejected: {}", name, h.sequence, error));
      alive = grant(1);
    }
    if (!alive) drop("connection closed");
  }
}

void StreamReceiver::store_rgb(std::shared_ptr<const ReceivedRgb> frame) {
  std::shared_ptr<const ReceivedDepth> best;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    rgb_history_.push_back(frame);
    if (rgb_history_.size() > options_.history_frames) rgb_history_.pop_front();
    for (const auto& d : depth_history_) {
      if (!best || std::llabs(d->info.capture_timestamp_us - frame->info.capture_timestamp_us) <
                       std::llabs(best->info.capture_timestamp_us - frame->info.capture_timestamp_us)) {
        best = d;
      }
    }
  }
  if (best) consider_pair(frame, best);
}

void StreamReceiver::store_depth(std::shared_ptr<const ReceivedDepth> frame) {
  std::shared_ptr<const ReceivedRgb> best;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    depth_history_.push_back(frame);
    if (depth_history_.size() > options_.history_frames) depth_history_.pop_front();
    for (const auto& r : rgb_history_) {
      if (!best || std::llabs(r->info.capture_timestamp_us - frame->info.capture_timestamp_us) <
                       std::llabs(best->info.capture_timestamp_us - frame->info.capture_timestamp_us)) {
        best = r;
      }
    }
  }
  if (best) consider_pair(best, frame);
}

void StreamReceiver::consider_pair(const std::shared_ptr<const ReceivedRgb>& rgb,
                                   const std::shared_ptr<const ReceivedDepth>& depth) {
  RgbdPair candidate;
  candidate.rgb = rgb;
  candidate.depth = depth;
  if (candidate.gap_us() > options_.max_pair_gap_us) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (newest_pair_) {
      const auto& cur = *newest_pair_;
      const std::int64_t t_new = rgb->info.capture_timestamp_us;
      const std::int64_t t_cur = cur.rgb->info.capture_timestamp_us;
      // Newer RGB wins; for the same RGB image a closer depth image wins. Timestamps restarting
      // far below the current pair (streamer restarted, replay looped) also start a new pairing.
      const bool restarted = t_new + 1'000'000 < t_cur;
      const bool better = t_new > t_cur || (rgb == cur.rgb && candidate.gap_us() < cur.gap_us());
      if (!better && !restarted) return;
      candidate.pair_id = cur.pair_id + 1;
    } else {
      candidate.pair_id = 1;
    }
    candidate.intrinsics = rgb_intrinsics_;
    newest_pair_ = candidate;
    ++counters_.pairs;
  }
  pair_ready_.notify_all();
}

std::optional<RgbdPair> StreamReceiver::newest_pair() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return newest_pair_;
}

std::optional<RgbdPair> StreamReceiver::wait_for_pair(std::uint64_t after_pair_id, int timeout_ms) const {
  std::unique_lock<std::mutex> lock(mutex_);
  const bool ready = pair_ready_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] {
    return newest_pair_ && newest_pair_->pair_id > after_pair_id;
  });
  if (!ready) return std::nullopt;
  return newest_pair_;
}

std::shared_ptr<const ReceivedRgb> StreamReceiver::newest_rgb() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return rgb_history_.empty() ? nullptr : rgb_history_.back();
}

std::shared_ptr<const ReceivedDepth> StreamReceiver::newest_depth() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return depth_history_.empty() ? nullptr : depth_history_.back();
}

ReceiverCounters StreamReceiver::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

}  // namespace rgbdquad::receiver
