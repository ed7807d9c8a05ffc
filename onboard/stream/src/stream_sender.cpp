// Stream sender: connect/handshake/credit loop with reconnect.
#include "rgbdquad/stream/stream_sender.h"

#include <poll.h>
#include <pthread.h>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/stream/payload_encoder.h"

namespace rgbdquad::stream {
namespace {
// Read buffer for StreamChallenge/HandshakeAck/FrameRequests (a few dozen bytes each).
constexpr std::size_t kReadChunkBytes = 4096;
}  // namespace

std::size_t choose_frame(const std::vector<std::int64_t>& capture_us, std::int64_t hint,
                         std::int64_t hint_used_before) {
  const std::size_t newest = capture_us.size() - 1;
  if (hint == PairHint::kNone || hint == hint_used_before) return newest;
  const auto gap = [&](std::size_t k) {
    const std::int64_t d = capture_us[k] - hint;
    return d < 0 ? -d : d;
  };
  std::size_t best = newest;
  for (std::size_t i = newest; i-- > 0;) {  // newest to oldest: a tie keeps the newer frame
    if (gap(i) < gap(best)) best = i;
  }
  return best;
}

bool StreamSenderOptions::is_valid(std::string* error) const {
  const auto format = kind == protocol::StreamKind::kRgb ? protocol::PixelFormat::kRgb8
                                                         : protocol::PixelFormat::kDepth16;
  if (host.empty())
    *error = "host is empty";
  else if (port == 0)
    *error = "port must be 1..65535";
  else if (!protocol::encoding_allows_pixel_format(encoding, format))
    *error = "encoding does not fit the stream";
  else if (width_px <= 0 || height_px <= 0 || width_px > 4096 || height_px > 4096)
    *error = "size must be 1..4096 px";
  else if (jpeg_quality < 1 || jpeg_quality > 100)
    *error = "jpeg_quality must be 1..100";
  else if (zstd_level < 1 || zstd_level > 19)
    *error = "zstd_level must be 1..19";
  else if (backoff_first_ms < 1 || backoff_max_ms < backoff_first_ms || backoff_max_ms > 1000)
    *error = "backoff must satisfy 1 <= first <= max <= 1000 ms";
  else if (held_frames < 1 || held_frames > 30)
    *error = "held_frames must be 1..30";
  else if (connect_timeout_ms < 1 || handshake_timeout_ms < 1 || stall_timeout_ms < 1 ||
           credit_idle_timeout_ms < 1)
    *error = "timeouts must be >= 1 ms";
  else if (kind == protocol::StreamKind::kDepth &&
           !(depth_units_per_m > 0 && depth_units_per_m < 1e6))
    *error = "depth_units_per_m must be in (0, 1e6)";
  else if (std::all_of(key.begin(), key.end(), [](std::uint8_t b) { return b == 0; }))
    *error = "no stream key (stream_key_file): the receiver accepts only a signed handshake";
  else
    return true;
  return false;
}

StreamSender::StreamSender(const StreamSenderOptions& options, capture::Clock* clock,
                           std::shared_ptr<spdlog::logger> logger)
    : options_(options), clock_(clock), log_(std::move(logger)) {
  std::string why;
  if (!options_.is_valid(&why)) throw std::invalid_argument("stream sender: " + why);
  if (!log_)
    log_ =
        std::make_shared<spdlog::logger>("null", std::make_shared<spdlog::sinks::null_sink_mt>());
  encoder_ = std::make_unique<PayloadEncoder>(options_.kind, options_.encoding,
                                              options_.jpeg_quality, options_.zstd_level);
  raw_encoder_ = std::make_unique<PayloadEncoder>(options_.kind, protocol::Encoding::kRaw,
                                                  options_.jpeg_quality, options_.zstd_level);
  thread_ = std::thread([this] { run(); });
}

StreamSender::~StreamSender() {
  stopping_ = true;
  stop_waker_.wake();
  thread_.join();
}

void StreamSender::publish(capture::SourceFrame frame) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.published;
    mailbox_.emplace_back(next_sequence_++, std::move(frame));
    if (mailbox_.size() > options_.held_frames) {
      mailbox_.pop_front();
      ++counters_.superseded;
    }
  }
  frame_waker_.wake();
}

SenderCounters StreamSender::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

void StreamSender::run() {
  const char* kind = protocol::to_string(options_.kind).data();
  // Named so top -H / ps -L attribute its CPU (Linux keeps 15 characters).
  pthread_setname_np(pthread_self(),
                     options_.kind == protocol::StreamKind::kRgb ? "tx-rgb" : "tx-depth");
  net::Backoff backoff(options_.backoff_first_ms, options_.backoff_max_ms);
  std::string last_error;
  // Negotiation: offer the configured encoding; if the receiver refuses it, offer raw at once
  // (when raw_fallback), and offer the configured one again on the next connection.
  bool offer_raw = false;
  while (!stopping_) {
    std::string error;
    current_encoding_ = offer_raw ? protocol::Encoding::kRaw : options_.encoding;
    auto fd = net::connect_tcp(options_.host, options_.port, options_.connect_timeout_ms,
                               stop_waker_, &error);
    ConnectionEnd end;
    if (fd) {
      end = serve_connection(fd->get(), [&] {
        backoff.reset();
        last_error.clear();
      });
    } else {
      end.why = error;
    }
    if (end.was_live) {
      connected_ = false;
      offer_raw = false;
      if (!stopping_) log_->warn("{} stream: {}; reconnecting", kind, end.why);
      std::lock_guard<std::mutex> lock(mutex_);
      ++counters_.disconnects;
      continue;  // reconnect at once: the server may already be back
    }
    if (stopping_) break;
    if (end.refused) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++counters_.refused;
    }
    if (end.refused && !offer_raw && options_.raw_fallback &&
        options_.encoding != protocol::Encoding::kRaw) {
      log_->warn("{} stream: {}; offering raw instead", kind, end.why);
      offer_raw = true;
      continue;
    }
    offer_raw = false;
    if (end.why != last_error) {  // log each new reason once, not every retry
      log_->warn("{} stream: {}:{}: {}; retrying (backoff <= {} ms)", kind, options_.host,
                 options_.port, end.why, options_.backoff_max_ms);
      last_error = end.why;
    }
    pollfd stop{stop_waker_.fd(), POLLIN, 0};
    poll(&stop, 1, backoff.next_delay_ms());
  }
}

protocol::Handshake StreamSender::make_hello() const {
  protocol::Handshake hello;
  hello.stream_kind = options_.kind;
  hello.width = static_cast<std::uint16_t>(options_.width_px);
  hello.height = static_cast<std::uint16_t>(options_.height_px);
  hello.pixel_format = options_.kind == protocol::StreamKind::kRgb
                           ? protocol::PixelFormat::kRgb8
                           : protocol::PixelFormat::kDepth16;
  hello.encoding = current_encoding_;
  hello.intrinsics = options_.intrinsics;
  hello.depth_scale_units_per_m =
      options_.kind == protocol::StreamKind::kDepth ? options_.depth_units_per_m : 0.0;
  hello.device_id = options_.device_id;
  return hello;
}

StreamSender::ConnectionEnd StreamSender::serve_connection(int fd,
                                                           const std::function<void()>& on_live) {
  SenderSessionOptions session_options;
  session_options.hello = make_hello();
  session_options.key = options_.key;
  session_options.handshake_timeout_us = std::int64_t{options_.handshake_timeout_ms} * 1000;
  session_options.credit_idle_timeout_us = std::int64_t{options_.credit_idle_timeout_ms} * 1000;
  SenderSession session(session_options, protocol::random_stream_nonce(), clock_->now_us());
  ConnectionEnd end;
  std::optional<std::uint32_t> last_sent;
  std::uint8_t buffer[kReadChunkBytes];
  // Sends what the session produced; true when the connection is over (`end` says why).
  auto carry_out = [&](SenderOutput&& out) {
    if (!out.send.empty()) {
      const net::IoStatus s = net::send_all(fd, out.send.data(), out.send.size(), stop_waker_,
                                            options_.stall_timeout_ms);
      if (s != net::IoStatus::kOk) {
        end.why = std::string("sending handshake: ") + net::to_string(s);
        return true;
      }
    }
    if (out.accepted) {
      end.was_live = true;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        ++counters_.connects;
      }
      on_live();
      log_->info("{} stream: connected to {}:{} ({})", protocol::to_string(options_.kind).data(),
                 options_.host, options_.port, encoding_name(current_encoding_));
      connected_ = true;
    }
    if (out.close) {
      end.why = *out.close;
      end.refused = out.refused;
      return true;
    }
    return false;
  };
  while (!stopping_) {
    // 1. One newest frame per credit.
    while (session.live() && session.credits() > 0) {
      const auto sent_before = last_sent;
      if (!send_newest(fd, &last_sent)) {
        end.why = "send failed";
        return end;
      }
      if (last_sent == sent_before) break;  // nothing new to send
      session.take_credit(clock_->now_us());
    }
    bool waiting;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      waiting = !mailbox_.empty();
    }
    const std::int64_t now_us = clock_->now_us();
    if (carry_out(session.on_tick(now_us, waiting))) return end;
    // 2. Wait for the receiver, a new frame (while live) or stop, at most until the next deadline.
    const int timeout_ms = static_cast<int>(std::clamp<std::int64_t>(
        (session.next_deadline_us() - now_us) / 1000 + 1, 1, options_.credit_idle_timeout_ms));
    pollfd fds[3] = {{fd, POLLIN, 0},
                     {session.live() ? frame_waker_.fd() : -1, POLLIN, 0},
                     {stop_waker_.fd(), POLLIN, 0}};
    const int n = poll(fds, 3, timeout_ms);
    if (n < 0 && errno != EINTR) {
      end.why = "poll failed";
      return end;
    }
    if (fds[2].revents & POLLIN) break;
    if (fds[1].revents & POLLIN) frame_waker_.clear();
    if (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) {
      std::size_t got = 0;
      const net::IoStatus s = net::read_some(fd, buffer, sizeof buffer, &got, stop_waker_, 0);
      if (s != net::IoStatus::kOk && s != net::IoStatus::kTimeout) {
        end.why =
            std::string(session.live() ? "connection lost (" : "waiting for handshake ack: (") +
            net::to_string(s) + ")";
        return end;
      }
      if (carry_out(session.on_bytes(clock_->now_us(), buffer, got))) return end;
    }
  }
  end.why = "stopping";
  return end;
}

bool StreamSender::send_newest(int fd, std::optional<std::uint32_t>* last_sent) {
  std::optional<capture::SourceFrame> frame;
  std::uint32_t sequence = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (mailbox_.empty()) return true;
    std::size_t pick = mailbox_.size() - 1;
    if (options_.pair_hint && options_.kind == protocol::StreamKind::kDepth) {
      std::vector<std::int64_t> times;
      for (const auto& held : mailbox_) {
        times.push_back(
            std::visit([](const auto& f) { return f.capture_timestamp_us; }, held.second));
      }
      const std::int64_t hint = options_.pair_hint->rgb_sent_us();
      pick = choose_frame(times, hint, hint_used_us_);
      hint_used_us_ = hint;
    }
    sequence = mailbox_[pick].first;
    frame.emplace(std::move(mailbox_[pick].second));
    // Frames older than the one sent will never be sent.
    counters_.superseded += pick;
    mailbox_.erase(mailbox_.begin(), mailbox_.begin() + static_cast<std::ptrdiff_t>(pick) + 1);
  }
  const std::int64_t start_us = clock_->now_us();
  std::string error;
  PayloadEncoder* encoder =
      current_encoding_ == options_.encoding ? encoder_.get() : raw_encoder_.get();
  const auto payload = encoder->encode(*frame, &error);
  const std::int64_t encoded_us = clock_->now_us();
  if (!payload) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.encode_errors;
    log_->error("encode failed: {}", error);
    *last_sent = sequence;
    return true;
  }
  protocol::FrameHeader header;
  header.sequence = sequence;
  header.capture_timestamp_us = static_cast<std::uint64_t>(
      std::visit([](const auto& f) { return f.capture_timestamp_us; }, *frame));
  header.send_timestamp_us = static_cast<std::uint64_t>(encoded_us);
  header.width = static_cast<std::uint16_t>(options_.width_px);
  header.height = static_cast<std::uint16_t>(options_.height_px);
  header.pixel_format = options_.kind == protocol::StreamKind::kRgb
                            ? protocol::PixelFormat::kRgb8
                            : protocol::PixelFormat::kDepth16;
  header.encoding = current_encoding_;
  header.payload_length = static_cast<std::uint32_t>(payload->size());
  // The colour image's accelerometer reading goes with it (protocol version 2, AccelSample).
  protocol::AccelSample accel;
  if (const auto* rgb = std::get_if<capture::RgbFrame>(&*frame); rgb && rgb->accel) {
    accel.valid = true;
    accel.capture_timestamp_us = static_cast<std::uint64_t>(rgb->accel->capture_timestamp_us);
    accel.f_mps2 = rgb->accel->f_mps2;
  }
  const auto bytes = protocol::encode_frame(header, payload->data(), payload->size(), accel);
  if (!bytes.ok()) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counters_.encode_errors;
    log_->error("frame {} rejected by the protocol encoder: {}", sequence, bytes.error);
    *last_sent = sequence;
    return true;
  }
  const net::IoStatus s = net::send_all(fd, bytes.bytes.data(), bytes.bytes.size(), stop_waker_,
                                        options_.stall_timeout_ms);
  if (s != net::IoStatus::kOk) {
    log_->warn("{} stream: send failed ({})", protocol::to_string(options_.kind).data(),
               net::to_string(s));
    return false;
  }
  *last_sent = sequence;
  if (options_.pair_hint && options_.kind == protocol::StreamKind::kRgb) {
    options_.pair_hint->set_rgb_sent_us(static_cast<std::int64_t>(header.capture_timestamp_us));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.sent;
  counters_.bytes_sent += bytes.bytes.size();
  counters_.encode_us_total += encoded_us - start_us;
  return true;
}

}  // namespace rgbdquad::stream
