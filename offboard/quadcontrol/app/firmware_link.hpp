// The firmware REST client of quad-control (thesis: two clients take turns sending the latest
// command as HTTP PUT and wait for the IMU reply, so one timed-out client never stalls control).
//
// Every period_ms the link picks the next idle client (round robin), asks the command provider for
// the command of this instant (the controller runs at send time, on the newest pose: no extra wait
// between computing and sending) and sends it (protocol/control: PUT /control?...&mac=...,
// SipHash-2-4 under the craft key, strictly increasing sequence). Before the first command it reads GET /status to continue above the sequence number
// the craft last accepted. Each request has its own deadline (timeout_ms); a client still waiting
// is skipped. Replies (with the craft's IMU reading) are timestamped on arrival and passed to the
// callback on the link's thread. Owns one io_context thread; joined in the destructor.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include "core/stick_mapping.hpp"
#include "link/control_codec.hpp"

namespace rgbdquad::quadcontrol {

struct FirmwareLinkOptions {
  std::string host = "192.168.240.1";  ///< Arduino Uno WiFi in its own access-point mode
  std::uint16_t port = 80;
  int timeout_ms = 100;  ///< > 2 periods: a reply later than this is useless for control
  int period_ms = 20;    ///< 50 commands/s, the rate the thesis' firmware handled
  std::string validate() const;
};

struct FirmwareLinkStats {
  std::uint64_t sent = 0, ok = 0, timeouts = 0, http_errors = 0, stale = 0, connect_errors = 0;
  double last_latency_ms = 0.0;
  double mean_latency_ms = 0.0;  ///< exponential mean over ~10 replies
  std::optional<ControlReply> last_reply;
  std::int64_t last_reply_us = 0;
  std::string last_error;
  std::uint32_t seq = 0;
};

class FirmwareLink {
 public:
  using ReplyCallback = std::function<void(std::int64_t received_us, const ControlReply& reply)>;
  /// Called on the link's thread just before each command is sent: the command for `now_us`, which
  /// will carry sequence number `seq`, or nullopt to send nothing this period (a blind landing hands
  /// the craft to its own failsafe). Must not call back into the link.
  using CommandProvider = std::function<std::optional<PwmCommand>(std::int64_t now_us, std::uint32_t seq)>;

  /// Resolves host:port (numeric addresses never block); throws std::runtime_error on failure.
  FirmwareLink(FirmwareLinkOptions options, ControlSpec spec, ControlKey key, CommandProvider provider,
               ReplyCallback callback);
  ~FirmwareLink();
  FirmwareLink(const FirmwareLink&) = delete;
  FirmwareLink& operator=(const FirmwareLink&) = delete;

  FirmwareLinkStats stats() const;

 private:
  struct Client {
    std::unique_ptr<boost::beast::tcp_stream> stream;
    boost::beast::http::request<boost::beast::http::empty_body> request;
    boost::beast::http::response<boost::beast::http::string_body> response;
    boost::beast::flat_buffer buffer;
    bool busy = false;
    bool is_status = false;
    std::int64_t started_us = 0;
  };

  void schedule();
  void tick();
  void start(Client& client);
  void finish(Client& client, boost::beast::error_code ec);

  FirmwareLinkOptions options_;
  ControlSpec spec_;
  ControlKey key_;
  CommandProvider provider_;
  ReplyCallback callback_;
  boost::asio::io_context io_;
  boost::asio::steady_timer timer_;
  std::chrono::steady_clock::time_point next_tick_{};
  boost::asio::ip::tcp::resolver::results_type endpoints_;
  std::array<Client, 2> clients_;
  std::size_t next_client_ = 0;
  bool seq_known_ = false;
  mutable std::mutex mutex_;
  FirmwareLinkStats stats_;
  std::thread thread_;
};

}  // namespace rgbdquad::quadcontrol
