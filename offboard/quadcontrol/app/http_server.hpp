// A small HTTP/1.1 server (Boost.Beast, one I/O thread) that hands every request to one handler.
// Used for the dashboard. Binds to the given address only; the caller decides whether that may be
// non-loopback (see main.cpp: a token is required for that). Joined in the destructor.
//
// Under hostile load:
//   - at most `max_sessions` connections are kept; a new one evicts the connection idle longest
//     (a browser reconnects), so idle sockets can neither exhaust the process's descriptors (the
//     frame and SLAM threads need some) nor lock the operator out;
//   - an accept that fails (EMFILE/ENFILE: descriptor limit; ENOBUFS/ENOMEM) is retried after a
//     back-off of 10 ms doubling to 1 s instead of at once (which spun one core at 100 %); one log
//     line when it starts failing and one when it accepts again;
//   - a malformed request is answered 400 (413 for a body over 64 KiB) before the connection
//   closes.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/http.hpp>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <string>
#include <thread>

namespace rgbdquad::quadcontrol {

using HttpRequest = boost::beast::http::request<boost::beast::http::string_body>;
using HttpResponse = boost::beast::http::response<boost::beast::http::string_body>;

class HttpSession;

class HttpServer {
 public:
  using Handler = std::function<HttpResponse(const HttpRequest&)>;
  /// Binds and starts serving; throws std::runtime_error when the address/port cannot be bound.
  /// `max_sessions` 0: a quarter of the soft RLIMIT_NOFILE, within [4, 256].
  HttpServer(const std::string& address, std::uint16_t port, Handler handler,
             std::size_t max_sessions = 0);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;
  /// The bound port (useful with port 0).
  std::uint16_t port() const { return port_; }
  std::size_t max_sessions() const { return max_sessions_; }

 private:
  void accept();
  void on_accept_error(const boost::system::error_code& ec);
  void evict_idlest();
  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::steady_timer retry_timer_;
  Handler handler_;
  std::uint16_t port_ = 0;
  std::size_t max_sessions_ = 0;
  std::list<std::weak_ptr<HttpSession>> sessions_;  // I/O thread only
  std::chrono::milliseconds backoff_{0};            // 0: accepting normally
  std::uint64_t failed_accepts_ = 0;                // in the current back-off episode
  std::thread thread_;
};

/// True for 127.0.0.0/8 and ::1.
bool is_loopback_address(const std::string& address);

}  // namespace rgbdquad::quadcontrol
