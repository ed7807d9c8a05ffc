// One stream connection of rgbd-streamer (RGB or depth) to the ground-station receiver.
//
// Contract (docs/protocol.md): connect to host:port, answer the receiver's StreamChallenge with a
// Handshake (stream kind, size, encoding, intrinsics, depth scale) signed with the stream key,
// wait for a HandshakeAck whose mac verifies (refused: offer raw next, see raw_fallback); the
// protocol logic is the socket-free SenderSession (sender_session.h). Then send one Frame per
// credit granted by the receiver's FrameRequests, always the NEWEST frame published since the last
// one sent (a slow receiver never gets a backlog: frames it had no credit for are overwritten,
// counted as "superseded"). On any failure (refused, closed, stalled, no credit for
// credit_idle_timeout_ms while frames wait) it reconnects forever with exponential backoff capped
// at backoff_max_ms.
//
// Thread safety: publish(), counters(), connected() may be called from any thread. The
// connection runs on a thread owned by the sender, started in the constructor and joined in the
// destructor.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "rgbdquad/capture/clock.h"
#include "rgbdquad/capture/frame.h"
#include "rgbdquad/net/socket.h"
#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/protocol/messages.hpp"
#include "rgbdquad/protocol/stream_auth.hpp"
#include "rgbdquad/stream/sender_session.h"

namespace spdlog {
class logger;
}

namespace rgbdquad::stream {

class PayloadEncoder;

// Shared by the two senders of one streamer: the RGB sender records the capture time of each RGB
// frame it sends; a depth sender with pair_with_rgb picks, from its few newest depth frames, the
// one nearest that time, so what reaches the ground station pairs up (<= 20 ms) even when the
// link carries only a few frames per second. Thread-safe.
class PairHint {
 public:
  void set_rgb_sent_us(std::int64_t capture_us) { rgb_sent_us_ = capture_us; }
  std::int64_t rgb_sent_us() const { return rgb_sent_us_; }
  static constexpr std::int64_t kNone = INT64_MIN;

 private:
  std::atomic<std::int64_t> rgb_sent_us_{kNone};
};

// Which held frame to send: the newest, unless `hint` is a new RGB time (not `hint_used_before`),
// then the one whose capture time is nearest it. `capture_us` is oldest first, non-empty.
std::size_t choose_frame(const std::vector<std::int64_t>& capture_us, std::int64_t hint,
                         std::int64_t hint_used_before);

struct StreamSenderOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 0;
  // The craft's stream key (protocol/stream_auth.hpp), from the key file; required.
  protocol::StreamKey key{};
  protocol::StreamKind kind = protocol::StreamKind::kRgb;
  protocol::Encoding encoding = protocol::Encoding::kRaw;
  int width_px = capture::kKinectWidthPx;
  int height_px = capture::kKinectHeightPx;
  protocol::CameraIntrinsics intrinsics;
  double depth_units_per_m = capture::kMillimetreUnitsPerM;  // handshake; ignored on RGB
  std::string device_id = "kinect";
  // If the receiver refuses the handshake (e.g. it does not accept this encoding), offer raw on
  // the next attempt, and the configured encoding again after that connection ends.
  bool raw_fallback = true;
  int jpeg_quality = 90;  // 90: ~10:1 on TUM frames at > 35 dB PSNR (make bench)
  int zstd_level = 1;     // 1: zstd's fastest level; higher buys little on delta-coded depth
  int connect_timeout_ms = 1000;
  // Reconnect backoff: 50 ms first retry (a restarting server is back within tens of ms), doubled
  // per failure, capped at 1000 ms (issue: "retry forever with capped backoff (<= 1 s)").
  int backoff_first_ms = 50;
  int backoff_max_ms = 1000;
  int handshake_timeout_ms = 2000;
  // A send making no progress for 2 s: the WiFi link is gone (TCP would wait minutes).
  int stall_timeout_ms = 2000;
  // Frames held for sending. 1 = strictly the newest. A depth sender with a PairHint holds 6
  // (200 ms at 30 fps: longer than one raw RGB frame takes on 120 Mbps) to find the RGB's partner.
  std::size_t held_frames = 1;
  std::shared_ptr<PairHint> pair_hint;  // RGB sender: written; depth sender: read (may be null)
  // No FrameRequest for 3 s while frames wait: the receiver library grants a credit as soon as it
  // has taken a frame (milliseconds), so 3 s of silence means a dead peer.
  int credit_idle_timeout_ms = 3000;

  bool is_valid(std::string* error) const;
};

struct SenderCounters {
  std::uint64_t published = 0;
  std::uint64_t sent = 0;
  std::uint64_t superseded = 0;  // published but dropped for a newer frame before a credit came
  std::uint64_t encode_errors = 0;
  std::uint64_t connects = 0;
  std::uint64_t disconnects = 0;
  std::uint64_t refused = 0;  // handshakes the receiver refused
  std::uint64_t bytes_sent = 0;
  std::int64_t encode_us_total = 0;
};

class StreamSender {
 public:
  // Throws std::invalid_argument for invalid options (start-up boundary). `clock` stamps
  // send_timestamp_us and times encoding; it must outlive the sender. `logger` may be null.
  StreamSender(const StreamSenderOptions& options, capture::Clock* clock,
               std::shared_ptr<spdlog::logger> logger);
  ~StreamSender();
  StreamSender(const StreamSender&) = delete;
  StreamSender& operator=(const StreamSender&) = delete;

  // Offers a validated frame of this stream's kind; it gets the next sequence number.
  void publish(capture::SourceFrame frame);
  SenderCounters counters() const;
  bool connected() const { return connected_; }
  const StreamSenderOptions& options() const { return options_; }

 private:
  struct ConnectionEnd {
    bool was_live = false;  // the handshake had been accepted
    bool refused = false;   // the receiver refused the handshake (signed answer)
    std::string why;
  };
  void run();
  protocol::Handshake make_hello() const;
  // One connection's lifetime around a SenderSession; returns when it ends (error or stop).
  // `on_live` runs once when the handshake is accepted.
  ConnectionEnd serve_connection(int fd, const std::function<void()>& on_live);
  bool send_newest(int fd, std::optional<std::uint32_t>* last_sent);

  StreamSenderOptions options_;
  capture::Clock* clock_;
  std::shared_ptr<spdlog::logger> log_;
  std::unique_ptr<PayloadEncoder> encoder_;      // configured encoding; connection thread only
  std::unique_ptr<PayloadEncoder> raw_encoder_;  // fallback; connection thread only
  protocol::Encoding current_encoding_ = protocol::Encoding::kRaw;  // connection thread only
  net::Waker stop_waker_;
  net::Waker frame_waker_;
  mutable std::mutex mutex_;  // guards mailbox_, next_sequence_, counters_
  std::deque<std::pair<std::uint32_t, capture::SourceFrame>>
      mailbox_;                                  // (sequence, frame), oldest first
  std::int64_t hint_used_us_ = PairHint::kNone;  // connection thread only
  std::uint32_t next_sequence_ = 0;
  SenderCounters counters_;
  std::atomic<bool> stopping_{false};
  std::atomic<bool> connected_{false};
  std::thread thread_;
};

}  // namespace rgbdquad::stream
