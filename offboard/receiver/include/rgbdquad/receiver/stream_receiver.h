// Ground-station side of the two RGB-D stream links: listens on the RGB and depth ports, accepts
// rgbd-streamer's connections, checks the Handshake (protocol version, schema hash, stream kind,
// size, encoding), grants frame credits, validates every Frame (envelope CRCs by the protocol
// StreamDecoder; size, format and encoding against the handshake; payload decodes), and pairs
// RGB with depth by nearest capture timestamp. Consumers (SLAM server, control loop) read the
// newest pair.
//
// Authentication: every connection gets a StreamChallenge; its Handshake must carry a
// mac over that challenge under the craft's stream key (protocol/stream_auth.hpp), so only the
// craft's streamer is accepted and a recorded handshake is refused.
// Hostile peers: a new connection is only a candidate until its handshake is accepted (within 2 s
// of the connect, first message); only then does it replace the live streamer, so the streamer
// may reconnect at any moment but a raw connect, garbage or a peer without the key displaces
// nothing. Up to 4 candidates wait at once. The protocol logic of one connection is the
// socket-free ReceiverSession (receiver_session.h); this class is its socket shell. Log lines
// caused by a peer's input are rate-limited (log_throttle.h). A failed accept (descriptor limit)
// pauses the listener 100 ms instead of spinning.
//
// Thread safety: all public members may be called from any thread. Two I/O threads (one per
// port) are owned by the receiver, started in the constructor and joined in the destructor.
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "rgbdquad/net/socket.h"
#include "rgbdquad/protocol/messages.hpp"
#include "rgbdquad/protocol/stream_auth.hpp"

namespace spdlog {
class logger;
}

namespace rgbdquad::receiver {

struct FrameInfo {
  std::uint32_t sequence = 0;
  std::int64_t capture_timestamp_us = 0;  // sensor clock (streamer side)
  std::int64_t send_timestamp_us = 0;     // streamer's monotonic clock at encode
  std::int64_t receive_timestamp_us = 0;  // receiver clock when the frame was complete
  protocol::Encoding encoding = protocol::Encoding::kRaw;
  std::size_t wire_bytes = 0;  // envelope bytes of the Frame message
  std::int64_t decode_us = 0;  // time to decode the payload
  int width = 0;
  int height = 0;
};

struct ReceivedRgb {
  FrameInfo info;
  std::vector<std::uint8_t> rgb;  // width*height*3, R,G,B
  // The Kinect's accelerometer sample sent with this image (sensor axes, m/s^2; not valid from a
  // streamer without one or of protocol version 1). Rotated into the camera frame by SLAM's gate.
  protocol::AccelSample accel;
  // The payload as it came off the link when it was encoded (info.encoding kRgbJpeg: one JFIF
  // image), shared so a recorder can store it without re-encoding; null for raw frames.
  std::shared_ptr<const std::vector<std::uint8_t>> encoded;
};

struct ReceivedDepth {
  FrameInfo info;
  double units_per_m = 1000.0;       // from the depth handshake
  std::vector<std::uint16_t> depth;  // width*height, 0 = no reading
  // The payload as received when encoded (info.encoding kDepthRvl / kDepthZstdDelta,
  // protocol/encodings/README.md), shared for a recorder; null for raw frames.
  std::shared_ptr<const std::vector<std::uint8_t>> encoded;
};

struct RgbdPair {
  std::uint64_t pair_id = 0;  // increases whenever the newest pair changes
  std::shared_ptr<const ReceivedRgb> rgb;
  std::shared_ptr<const ReceivedDepth> depth;
  protocol::CameraIntrinsics intrinsics;  // of the RGB image (depth is registered to it)
  std::int64_t gap_us() const {
    const std::int64_t d = rgb->info.capture_timestamp_us - depth->info.capture_timestamp_us;
    return d < 0 ? -d : d;
  }
};

struct ReceiverOptions {
  // Loopback by default: listening on every interface is an explicit choice; on the craft's WiFi
  // bind the ground station's address on that network.
  std::string bind_address = "127.0.0.1";
  // The craft's stream key (protocol/stream_auth.hpp; read from a key file with
  // protocol::load_stream_key_file): only a streamer holding it is accepted. Required.
  protocol::StreamKey key{};
  std::uint16_t rgb_port = 5600;  // 0 = any free port (tests)
  std::uint16_t depth_port = 5601;
  // Frames in flight per stream: 2 hides one round trip (so the link stays busy) while keeping at
  // most one frame that is older than the newest at send time.
  std::uint16_t credits_in_flight = 2;
  // Pair RGB and depth only when their capture times differ by at most 20 ms: the TUM benchmark's
  // association rule; Kinect streams at 30 fps are at most 16.7 ms apart.
  std::int64_t max_pair_gap_us = 20000;
  // Frames kept per stream to search for the nearest partner: 8 = 267 ms at 30 fps, enough when
  // one stream runs several frames ahead of the other.
  std::size_t history_frames = 8;
  // Encodings this receiver accepts in a handshake; empty = every encoding it can decode. A
  // streamer offering another one is refused and falls back to raw.
  std::vector<protocol::Encoding> accepted_encodings;
  // A connection silent this long while it owes frames is dropped (WiFi gone without a FIN);
  // the streamer reconnects.
  int idle_timeout_ms = 5000;

  bool is_valid(std::string* error) const;
};

struct ChannelCounters {
  std::uint64_t connections = 0;
  std::uint64_t replaced = 0;  // live connection replaced by a new one whose handshake was accepted
  std::uint64_t dropped_before_handshake =
      0;  // new connections that never became live (garbage,
          // refused or no handshake within 2 s): nothing displaced
  std::uint64_t disconnects = 0;
  std::uint64_t handshakes_refused = 0;
  std::uint64_t frames = 0;           // valid frames stored
  std::uint64_t crc_errors = 0;       // header or body CRC mismatch (frame dropped)
  std::uint64_t protocol_errors = 0;  // other envelope/body errors
  std::uint64_t invalid_frames = 0;   // frame disagrees with the handshake or fails to decode
  std::uint64_t wire_bytes = 0;
  std::int64_t decode_us_total = 0;
};

struct ReceiverCounters {
  ChannelCounters rgb;
  ChannelCounters depth;
  std::uint64_t pairs = 0;
};

class StreamReceiver {
 public:
  // Binds both ports (throws std::runtime_error with the reason: start-up boundary). `now_us`
  // is the receiver's monotonic clock in microseconds (stamps receive times, times decoding).
  StreamReceiver(const ReceiverOptions& options, std::function<std::int64_t()> now_us,
                 std::shared_ptr<spdlog::logger> logger);
  ~StreamReceiver();
  StreamReceiver(const StreamReceiver&) = delete;
  StreamReceiver& operator=(const StreamReceiver&) = delete;

  std::uint16_t rgb_port() const { return ports_[0]; }
  std::uint16_t depth_port() const { return ports_[1]; }

  std::optional<RgbdPair> newest_pair() const;
  // Waits until the newest pair's id exceeds after_pair_id; nullopt on timeout.
  std::optional<RgbdPair> wait_for_pair(std::uint64_t after_pair_id, int timeout_ms) const;
  std::shared_ptr<const ReceivedRgb> newest_rgb() const;
  std::shared_ptr<const ReceivedDepth> newest_depth() const;
  ReceiverCounters counters() const;
  bool connected(protocol::StreamKind kind) const;

 private:
  class Channel;  // one stream's listener and connections, served by its own thread
  void serve(int index);
  void store_rgb(std::shared_ptr<const ReceivedRgb> frame);
  void store_depth(std::shared_ptr<const ReceivedDepth> frame);
  void consider_pair(const std::shared_ptr<const ReceivedRgb>& rgb,
                     const std::shared_ptr<const ReceivedDepth>& depth);

  ReceiverOptions options_;
  std::function<std::int64_t()> now_us_;
  std::shared_ptr<spdlog::logger> log_;
  net::Waker stop_waker_;
  std::array<net::UniqueFd, 2> listeners_;
  std::array<std::uint16_t, 2> ports_{};
  std::array<std::atomic<bool>, 2> connected_{};
  mutable std::mutex mutex_;  // guards everything below
  mutable std::condition_variable pair_ready_;
  std::deque<std::shared_ptr<const ReceivedRgb>> rgb_history_;
  std::deque<std::shared_ptr<const ReceivedDepth>> depth_history_;
  std::optional<RgbdPair> newest_pair_;
  protocol::CameraIntrinsics rgb_intrinsics_;
  ReceiverCounters counters_;
  std::array<std::thread, 2> threads_;
};

}  // namespace rgbdquad::receiver
