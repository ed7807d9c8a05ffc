// Ground-station receiver of the RGB and depth streams.
#include "rgbdquad/receiver/stream_receiver.h"

#include <poll.h>
#include <pthread.h>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "rgbdquad/encodings/depth_codec.h"
#include "rgbdquad/encodings/jpeg_codec.h"
#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/receiver/log_throttle.h"
#include "rgbdquad/receiver/nearest_stamp.h"
#include "rgbdquad/receiver/receiver_session.h"

namespace rgbdquad::receiver {
namespace {

using protocol::Encoding;
using protocol::StreamKind;

// Socket read size: 256 KiB moves a raw RGB frame (921 KB) in four reads.
constexpr std::size_t kReadChunkBytes = 256 * 1024;
// A FrameRequest must leave within 1 s or the link is considered dead.
constexpr int kSendTimeoutMs = 1000;
// A new connection is a candidate until its handshake is accepted: only then
// may it replace the live streamer (a raw connect, or random bytes, used to
// drop the real streamer at once), and it is accepted only when its mac
// verifies under the stream key. The streamer answers the challenge at once; 2
// s is an absolute deadline from the connect (not restarted per byte, so a
// dripping peer cannot hold a slot).
constexpr std::int64_t kHandshakeDeadlineUs = 2'000'000;
// Candidates at once: the streamer reconnecting plus a few stray peers; more
// evicts the oldest.
constexpr std::size_t kMaxCandidates = 4;
// A failed accept (EMFILE at the descriptor limit) leaves the connection in the
// backlog, so the listener stays readable: it is left out of poll() this long
// instead of spinning a core.
constexpr std::int64_t kAcceptBackoffUs = 100'000;

// One accepted connection: the socket and its socket-free session
// (receiver_session.h).
struct Connection {
  net::UniqueFd fd;
  std::string peer;
  ReceiverSession session;
};

// Decoded pixels of a frame the session accepted; nullopt with `error` when the
// payload does not decode (JPEG/RVL/zstd damage the envelope CRC did not
// catch).
struct DecodedFrame {
  std::shared_ptr<const ReceivedRgb> rgb;
  std::shared_ptr<const ReceivedDepth> depth;
};
std::optional<DecodedFrame> decode_payload(const protocol::Frame& frame,
                                           const protocol::Handshake& hs, FrameInfo info,
                                           encodings::JpegDecoder& jpeg,
                                           const std::function<std::int64_t()>& now_us,
                                           std::string* error) {
  const auto& h = frame.image.header;
  const auto& payload = frame.image.payload;
  const std::int64_t start_us = now_us();
  DecodedFrame out;
  if (hs.stream_kind == StreamKind::kRgb) {
    auto rgb = std::make_shared<ReceivedRgb>();
    if (h.encoding == Encoding::kRgbJpeg) {
      auto pixels = jpeg.decode(payload.data(), payload.size(), h.width, h.height, error);
      if (!pixels) return std::nullopt;
      rgb->rgb = std::move(*pixels);
      rgb->encoded = std::make_shared<const std::vector<std::uint8_t>>(payload);
    } else {
      rgb->rgb = payload;  // RAW: the protocol decoder checked the length
    }
    rgb->info = info;
    rgb->accel = frame.accel;
    rgb->info.decode_us = now_us() - start_us;
    out.rgb = std::move(rgb);
    return out;
  }
  const encodings::DepthCodec codec =
      h.encoding == Encoding::kDepthRvl         ? encodings::DepthCodec::kRvl
      : h.encoding == Encoding::kDepthZstdDelta ? encodings::DepthCodec::kZstdDelta
                                                : encodings::DepthCodec::kRaw;
  auto pixels =
      encodings::decode_depth(codec, payload.data(), payload.size(), h.width, h.height, error);
  if (!pixels) return std::nullopt;
  auto depth = std::make_shared<ReceivedDepth>();
  depth->info = info;
  depth->info.decode_us = now_us() - start_us;
  depth->units_per_m = hs.depth_scale_units_per_m;
  depth->depth = std::move(*pixels);
  if (codec != encodings::DepthCodec::kRaw)
    depth->encoded = std::make_shared<const std::vector<std::uint8_t>>(payload);
  out.depth = std::move(depth);
  return out;
}

bool key_is_set(const protocol::StreamKey& key) {
  return std::any_of(key.begin(), key.end(), [](std::uint8_t b) { return b != 0; });
}

}  // namespace

bool ReceiverOptions::is_valid(std::string* error) const {
  if (credits_in_flight < 1 || credits_in_flight > protocol::kMaxCreditsPerRequest)
    *error = "credits_in_flight must be 1..8";
  else if (max_pair_gap_us < 0)
    *error = "max_pair_gap_us must be >= 0";
  else if (history_frames < 1 || history_frames > 64)
    *error = "history_frames must be 1..64";
  else if (idle_timeout_ms < 100)
    *error = "idle_timeout_ms must be >= 100";
  else if (rgb_port != 0 && rgb_port == depth_port)
    *error = "RGB and depth ports must differ";
  else if (!key_is_set(key))
    *error =
        "no stream key: set the craft's stream key file (quad-control: "
        "stream.key_file; "
        "rgbd-receiver: --key-file); only a streamer holding it is accepted";
  else
    return true;
  return false;
}

StreamReceiver::StreamReceiver(const ReceiverOptions& options, std::function<std::int64_t()> now_us,
                               std::shared_ptr<spdlog::logger> logger)
    : options_(options), now_us_(std::move(now_us)), log_(std::move(logger)) {
  std::string why;
  if (!options_.is_valid(&why)) throw std::runtime_error("receiver: " + why);
  if (!log_)
    log_ =
        std::make_shared<spdlog::logger>("null", std::make_shared<spdlog::sinks::null_sink_mt>());
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

// One stream's channel, run by its own thread: the listener, the live
// connection (the streamer, its handshake accepted) and the candidates
// (connected, handshake not yet accepted). Each connection's bytes go through
// its socket-free ReceiverSession; this object carries out what the session
// asks (send, close), decodes and stores the frames and counts every event.
class StreamReceiver::Channel {
 public:
  Channel(StreamReceiver& receiver, int index)
      : rx_(receiver),
        index_(index),
        kind_(index == 0 ? StreamKind::kRgb : StreamKind::kDepth),
        name_(index == 0 ? "rgb" : "depth"),
        buffer_(kReadChunkBytes) {
    session_options_.kind = kind_;
    session_options_.key = rx_.options_.key;
    session_options_.credits_in_flight = rx_.options_.credits_in_flight;
    session_options_.accepted_encodings = rx_.options_.accepted_encodings;
    session_options_.handshake_deadline_us = kHandshakeDeadlineUs;
    session_options_.idle_timeout_us = std::int64_t{rx_.options_.idle_timeout_ms} * 1000;
  }

  // Serves until the receiver's stop waker fires (or poll fails).
  void run() {
    // Named so top -H / ps -L attribute its CPU (Linux keeps 15 characters).
    pthread_setname_np(pthread_self(), index_ == 0 ? "rx-rgb" : "rx-depth");
    while (true) {
      const std::int64_t now = rx_.now_us_();
      std::vector<pollfd> fds = poll_set(now);
      const int n = poll(fds.data(), fds.size(), poll_timeout_ms(now));
      if (n < 0 && errno != EINTR) break;
      if (fds[0].revents & POLLIN) break;
      report_suppressed();
      serve_candidates(fds);
      if (fds[1].revents & POLLIN) accept_one();
      if (live_) serve_live(fds[2].revents);
    }
  }

 private:
  ChannelCounters& counter() { return index_ == 0 ? rx_.counters_.rgb : rx_.counters_.depth; }

  void count(std::uint64_t ChannelCounters::*field) {
    std::lock_guard<std::mutex> lock(rx_.mutex_);
    ++(counter().*field);
  }

  // Every line a peer's input can cause goes through one throttle per stream:
  // garbage used to give one line per malformed envelope (every 16 bytes).
  void peer_log(spdlog::level::level_enum level, const std::string& line) {
    std::uint64_t suppressed = 0;
    if (!throttle_.allow(rx_.now_us_(), &suppressed)) return;
    if (suppressed > 0) {
      rx_.log_->log(level, "{} (and {} similar lines suppressed)", line, suppressed);
    } else {
      rx_.log_->log(level, "{}", line);
    }
  }

  void report_suppressed() {
    if (const std::uint64_t quiet = throttle_.take_unreported(rx_.now_us_()); quiet > 0)
      rx_.log_->warn(
          "{} stream: {} similar lines suppressed (no line since to "
          "carry the count)",
          name_, quiet);
  }

  // The stop waker, the listener (left out while accepting is paused), the live
  // connection, then the candidates in order.
  std::vector<pollfd> poll_set(std::int64_t now) const {
    const bool accept_paused = now < accept_paused_until_us_;
    std::vector<pollfd> fds = {{rx_.stop_waker_.fd(), POLLIN, 0},
                               {accept_paused ? -1 : rx_.listeners_[index_].get(), POLLIN, 0},
                               {live_ ? live_->fd.get() : -1, POLLIN, 0}};
    for (const Connection& c : candidates_) fds.push_back({c.fd.get(), POLLIN, 0});
    return fds;
  }

  // Until the nearest session deadline, accept pause or throttle report; at
  // most the idle timeout.
  int poll_timeout_ms(std::int64_t now) const {
    std::int64_t next_us = live_ ? live_->session.next_deadline_us()
                                 : now + std::int64_t{rx_.options_.idle_timeout_ms} * 1000;
    for (const Connection& c : candidates_)
      next_us = std::min(next_us, c.session.next_deadline_us());
    if (now < accept_paused_until_us_) next_us = std::min(next_us, accept_paused_until_us_);
    next_us = std::min(next_us, throttle_.unreported_due_us());
    return static_cast<int>(
        std::clamp<std::int64_t>((next_us - now) / 1000 + 1, 0, rx_.options_.idle_timeout_ms));
  }

  // A frame the session accepted: decode its payload, store it, count it.
  void take_frame(const protocol::Frame& frame, std::size_t wire_bytes,
                  const protocol::Handshake& hs) {
    const auto& h = frame.image.header;
    FrameInfo info;
    info.sequence = h.sequence;
    info.capture_timestamp_us = static_cast<std::int64_t>(h.capture_timestamp_us);
    info.send_timestamp_us = static_cast<std::int64_t>(h.send_timestamp_us);
    info.receive_timestamp_us = rx_.now_us_();
    info.encoding = h.encoding;
    info.width = h.width;
    info.height = h.height;
    info.wire_bytes = wire_bytes;
    std::string error;
    const std::int64_t start_us = rx_.now_us_();
    auto decoded = decode_payload(frame, hs, info, jpeg_, rx_.now_us_, &error);
    if (decoded && decoded->rgb) rx_.store_rgb(std::move(decoded->rgb));
    if (decoded && decoded->depth) rx_.store_depth(std::move(decoded->depth));
    {
      std::lock_guard<std::mutex> lock(rx_.mutex_);
      if (decoded) {
        ++counter().frames;
        counter().wire_bytes += wire_bytes;
        counter().decode_us_total += rx_.now_us_() - start_us;
      } else {
        ++counter().invalid_frames;
      }
    }
    if (!decoded)
      peer_log(spdlog::level::warn,
               fmt::format("{} stream: frame {} rejected: {}", name_, h.sequence, error));
  }

  // One event a session reported on connection `c`.
  void on_event(Connection& c, ReceiverEvent& e) {
    switch (e.kind) {
      case ReceiverEvent::Kind::kHandshakeAccepted:
        if (kind_ == StreamKind::kRgb) {
          std::lock_guard<std::mutex> lock(rx_.mutex_);
          rx_.rgb_intrinsics_ = e.handshake->intrinsics;
        }
        rx_.log_->info("{} stream: {} connected ({}x{}, {}, device '{}')", name_, c.peer,
                       e.handshake->width, e.handshake->height,
                       protocol::to_string(e.handshake->encoding).data(), e.handshake->device_id);
        break;
      case ReceiverEvent::Kind::kHandshakeRefused:
        count(&ChannelCounters::handshakes_refused);
        peer_log(spdlog::level::err,
                 fmt::format("{} stream: refused handshake from {}: {}", name_, c.peer, e.detail));
        break;
      case ReceiverEvent::Kind::kFrame:
        take_frame(*e.frame, e.wire_bytes, *c.session.handshake());
        break;
      case ReceiverEvent::Kind::kFrameMismatch:
        count(&ChannelCounters::invalid_frames);
        peer_log(spdlog::level::warn, fmt::format("{} stream: {}", name_, e.detail));
        break;
      case ReceiverEvent::Kind::kDecodeError: {
        const bool crc = e.error == protocol::DecodeError::kBadBodyCrc ||
                         e.error == protocol::DecodeError::kBadHeaderCrc;
        count(crc && c.session.live() ? &ChannelCounters::crc_errors
                                      : &ChannelCounters::protocol_errors);
        if (c.session.live()) {
          peer_log(spdlog::level::warn,
                   fmt::format("{} stream: dropped bytes from {}: {} ({})", name_, c.peer,
                               protocol::to_string(e.error), e.detail));
        }
        break;
      }
      case ReceiverEvent::Kind::kUnexpectedMessage:
        count(&ChannelCounters::protocol_errors);
        if (c.session.live())
          peer_log(spdlog::level::warn,
                   fmt::format("{} stream: {} from {}", name_, e.detail, c.peer));
        break;
    }
  }

  // Carries out what a session asked for; returns false when the connection is
  // to be closed.
  bool apply(Connection& c, ReceiverOutput&& out) {
    for (ReceiverEvent& e : out.events) on_event(c, e);
    if (!out.send.empty() && net::send_all(c.fd.get(), out.send.data(), out.send.size(),
                                           rx_.stop_waker_, kSendTimeoutMs) != net::IoStatus::kOk) {
      if (!out.close) out.close = "connection closed";
    }
    return !out.close;
  }

  void drop_live(const std::string& why) {
    peer_log(spdlog::level::warn, fmt::format("{} stream: {} from {}", name_, why, live_->peer));
    live_.reset();
    rx_.connected_[index_] = false;
    count(&ChannelCounters::disconnects);
  }

  void drop_candidate(std::size_t i, const std::string& why) {
    peer_log(spdlog::level::warn,
             fmt::format("{} stream: {} from {} (not a live connection: nothing displaced)", name_,
                         why, candidates_[i].peer));
    candidates_.erase(candidates_.begin() + static_cast<std::ptrdiff_t>(i));
    count(&ChannelCounters::dropped_before_handshake);
  }

  // Feeds what the socket has; returns the reason to close, or nullopt.
  std::optional<std::string> pump(Connection& c) {
    std::size_t got = 0;
    const net::IoStatus s =
        net::read_some(c.fd.get(), buffer_.data(), buffer_.size(), &got, rx_.stop_waker_, 0);
    if (s == net::IoStatus::kTimeout) return std::nullopt;
    if (s != net::IoStatus::kOk)
      return std::string(c.session.live() ? "" : "closed before its handshake: ") +
             net::to_string(s);
    ReceiverOutput out = c.session.on_bytes(rx_.now_us_(), buffer_.data(), got);
    std::optional<std::string> why = out.close;
    if (!apply(c, std::move(out))) return why ? *why : std::string("connection closed");
    return std::nullopt;
  }

  // Reads a connection that poll() flagged (`revents`) and runs its session's
  // timers; the reason to close it, or nullopt.
  std::optional<std::string> service(Connection& c, short revents) {
    std::optional<std::string> why;
    if (revents & (POLLIN | POLLHUP | POLLERR)) why = pump(c);
    if (!why) {
      ReceiverOutput tick = c.session.on_tick(rx_.now_us_());
      if (tick.close) why = *tick.close;
    }
    return why;
  }

  // Candidates: a handshake accepted makes one the live connection, replacing
  // the previous one.
  void serve_candidates(const std::vector<pollfd>& fds) {
    for (std::size_t i = candidates_.size(); i-- > 0;) {
      Connection& c = candidates_[i];
      if (const auto why = service(c, fds[3 + i].revents)) {
        drop_candidate(i, *why);
        continue;
      }
      if (!c.session.live()) continue;
      Connection next = std::move(c);
      candidates_.erase(candidates_.begin() + static_cast<std::ptrdiff_t>(i));
      promote(std::move(next));
    }
  }

  void promote(Connection&& next) {
    if (live_) {
      peer_log(spdlog::level::warn,
               fmt::format("{} stream: {} replaced by {} (its handshake accepted)", name_,
                           live_->peer, next.peer));
      std::lock_guard<std::mutex> lock(rx_.mutex_);
      ++counter().replaced;
      ++counter().disconnects;
    }
    live_ = std::move(next);
    rx_.connected_[index_] = true;
  }

  // A new connection becomes a candidate (evicting the oldest beyond
  // kMaxCandidates); a failed accept pauses accepting for kAcceptBackoffUs.
  void accept_one() {
    std::string peer;
    auto fd = net::accept_tcp(rx_.listeners_[index_], &peer);
    if (!fd) {
      accept_paused_until_us_ = rx_.now_us_() + kAcceptBackoffUs;
      return;
    }
    if (candidates_.size() >= kMaxCandidates)
      drop_candidate(0, "too many connections awaiting a handshake");
    count(&ChannelCounters::connections);
    Connection c{std::move(*fd), peer,
                 ReceiverSession(session_options_, protocol::random_stream_nonce(), rx_.now_us_())};
    if (apply(c, c.session.start())) {
      candidates_.push_back(std::move(c));
    } else {
      count(&ChannelCounters::dropped_before_handshake);
    }
  }

  void serve_live(short revents) {
    if (const auto why = service(*live_, revents)) drop_live(*why);
  }

  StreamReceiver& rx_;
  const int index_;
  const StreamKind kind_;
  const char* const name_;
  ReceiverSessionOptions session_options_;
  std::optional<Connection> live_;      // the streamer (its handshake accepted)
  std::vector<Connection> candidates_;  // connected, handshake not (yet) accepted
  std::int64_t accept_paused_until_us_ = 0;
  std::vector<std::uint8_t> buffer_;
  encodings::JpegDecoder jpeg_;
  LogThrottle throttle_;
};

void StreamReceiver::serve(int index) { Channel(*this, index).run(); }

namespace {
// A stored RGB or depth frame's capture time, the stamp frames are paired by.
constexpr auto capture_stamp_us = [](const auto& frame) -> std::int64_t {
  return frame->info.capture_timestamp_us;
};

// Keeps `frame` in its stream's `history` (the newest `max_frames`) and returns
// the frame of the other stream nearest to it in capture time (null when there
// is none). Caller holds the lock.
template <typename Frame, typename Partner>
std::shared_ptr<const Partner> remember_and_find_partner(
    std::deque<std::shared_ptr<const Frame>>& history,
    const std::deque<std::shared_ptr<const Partner>>& partners,
    const std::shared_ptr<const Frame>& frame, std::size_t max_frames) {
  history.push_back(frame);
  if (history.size() > max_frames) history.pop_front();
  const auto it = nearest_stamp(partners.begin(), partners.end(), frame->info.capture_timestamp_us,
                                capture_stamp_us);
  return it == partners.end() ? nullptr : *it;
}
}  // namespace

void StreamReceiver::store_rgb(std::shared_ptr<const ReceivedRgb> frame) {
  std::shared_ptr<const ReceivedDepth> best;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    best = remember_and_find_partner(rgb_history_, depth_history_, frame, options_.history_frames);
  }
  if (best) consider_pair(frame, best);
}

void StreamReceiver::store_depth(std::shared_ptr<const ReceivedDepth> frame) {
  std::shared_ptr<const ReceivedRgb> best;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    best = remember_and_find_partner(depth_history_, rgb_history_, frame, options_.history_frames);
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
      // Newer RGB wins; for the same RGB image a closer depth image wins.
      // Timestamps restarting far below the current pair (streamer restarted,
      // replay looped) also start a new pairing.
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

std::optional<RgbdPair> StreamReceiver::wait_for_pair(std::uint64_t after_pair_id,
                                                      int timeout_ms) const {
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
