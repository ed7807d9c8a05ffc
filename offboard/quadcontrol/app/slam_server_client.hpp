// SLAM link to slam-server (offboard/slamlink): protocol/'s SLAM messages over TCP (default
// 127.0.0.1:5700, so SLAM can also run on a bigger machine). SlamHello both ways (a peer with
// another protocol version or schema hash is refused loudly), then one RgbdFrame (RAW RGB8 +
// DEPTH16) per PoseUpdate. Same semantics as the in-process link: the newest frame is handed over
// and a frame arriving while the server is busy is dropped.
//
// Deadlines: connecting, the SlamHello answer and each frame's PoseUpdate (sending included) must
// complete within reply_timeout_ms, else the connection is dropped with the cause logged
// (slam_link_socket.hpp: every wait is a poll() with the time left). Frames keep flowing to the
// dashboard while slam-server is down.
//
// Maps: the client names its flight's map with an id (SlamHello.session_id; random per client,
// i.e. per quad-control run, unless configured). After a broken connection it reconnects at once
// (then at most once per reconnect_interval_ms) presenting the same id; slam-server keeps a map
// without its client for a grace period (30 s by default), so the reconnect continues the same map
// and world frame (SlamHello.resumed). Only a new map increments SlamResult::session, which is what
// makes the ground station re-anchor its floor frame. Every connect, resume, new map and
// disconnect is logged on stderr ("quad-control: SLAM link: ..."). The worker thread is joined in
// the destructor.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "app/slam_link.hpp"
#include "app/slam_link_socket.hpp"
#include "rgbdquad/protocol/codec.hpp"
#include "slam/core/thread_priority.hpp"

namespace rgbdquad::quadcontrol {

struct SlamServerOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 5700;    ///< slam-server's default
  int reply_timeout_ms = 5000;  ///< one frame's SLAM, generous for a loaded machine
  /// Retry period while slam-server is away. A restarted slam-server is back within its start-up
  /// (~0.1-0.3 s with the checkpoint load) of its supervisor's restart; retried every 1000 ms the
  /// link added up to 1 s more (0.48 s in a soak flight) to an outage that the controller's 2 s
  /// lost-hold must cover. A refused connect costs one SYN/RST exchange (well under 1 ms on
  /// loopback, a few ms on WiFi) in a thread that has no frame to serve meanwhile; 100 ms is 3
  /// frames at 30 fps.
  int reconnect_interval_ms = 100;
  std::uint64_t session_id = 0;  ///< 0: a random id per client (one flight per quad-control run)
  slam::ThreadPriorityOptions thread_priority;  ///< the link thread is on the real-time path
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

class SlamServerClient : public SlamLink {
 public:
  SlamServerClient(SlamServerOptions options, Callback callback);
  ~SlamServerClient() override;
  bool submit(const CameraFrame& frame) override;
  SlamStats stats() const override;
  std::string name() const override;
  SlamLinkStatus link_status() const override;

 private:
  using Clock = SlamLinkSocket::Clock;
  void run();
  bool connect(std::string* error);
  bool send(const protocol::Message& message, Clock::time_point deadline, std::string* error);
  std::optional<protocol::Message> receive(Clock::time_point deadline, const std::string& what,
                                           std::string* error);
  std::optional<SlamResult> exchange(const CameraFrame& frame, std::string* error);
  void disconnect();

  SlamServerOptions options_;
  Callback callback_;
  SlamLinkSocket socket_;
  bool connected_ = false;
  bool reconnect_now_ = false;  ///< a connection just broke: retry at once (resume)
  std::uint64_t session_ = 0;   ///< SlamResult::session: new maps started
  std::string last_connect_error_;
  std::int64_t last_attempt_us_ = 0;
  protocol::StreamDecoder decoder_;
  std::size_t decode_errors_ = 0;
  mutable std::mutex status_mutex_;
  SlamLinkStatus status_;
  FrameMailbox mailbox_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace rgbdquad::quadcontrol
