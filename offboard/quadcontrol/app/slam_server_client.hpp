// SLAM link to slam-server (offboard/slamlink): protocol/'s SLAM messages over loopback TCP
// (default 127.0.0.1:5700, so SLAM can also run on a bigger machine). SlamHello both ways (a peer
// with another protocol version or schema hash is refused loudly), then one RgbdFrame (RAW RGB8 +
// DEPTH16) per PoseUpdate. Same semantics as the in-process link: the newest frame is handed over
// and a frame arriving while the server is busy is dropped. Connects lazily on the worker thread
// and reconnects (at most once per reconnect_interval) after any error, so frames keep flowing to
// the dashboard while slam-server is down. The worker thread is joined in the destructor.
#pragma once

#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "app/slam_link.hpp"
#include "rgbdquad/protocol/codec.hpp"

namespace rgbdquad::quadcontrol {

struct SlamServerOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 5700;       ///< slam-server's default
  int reply_timeout_ms = 5000;     ///< one frame's SLAM, generous for a loaded machine
  int reconnect_interval_ms = 1000;
  std::string validate() const;
};

class SlamServerClient : public SlamLink {
 public:
  SlamServerClient(SlamServerOptions options, Callback callback);
  ~SlamServerClient() override;
  bool submit(const CameraFrame& frame) override;
  SlamStats stats() const override;
  std::string name() const override;

 private:
  void run();
  bool connect(std::string* error);
  bool send(const protocol::Message& message, std::string* error);
  std::optional<protocol::Message> receive(std::string* error);
  std::optional<SlamResult> exchange(const CameraFrame& frame, std::string* error);
  void disconnect();

  SlamServerOptions options_;
  Callback callback_;
  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket socket_;
  std::atomic<int> socket_fd_{-1};  ///< for shutdown() from the destructor
  bool connected_ = false;
  std::uint64_t session_ = 0;  ///< connections made (SlamResult::session)
  std::string last_connect_error_;
  std::int64_t last_attempt_us_ = 0;
  protocol::StreamDecoder decoder_;
  FrameMailbox mailbox_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace rgbdquad::quadcontrol
