// A small HTTP/1.1 server (Boost.Beast, one I/O thread) that hands every request to one handler.
// Used for the dashboard. Binds to the given address only; the caller decides whether that may be
// non-loopback (see main.cpp: a token is required for that). Joined in the destructor.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <thread>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/http.hpp>

namespace rgbdquad::quadcontrol {

using HttpRequest = boost::beast::http::request<boost::beast::http::string_body>;
using HttpResponse = boost::beast::http::response<boost::beast::http::string_body>;

class HttpServer {
 public:
  using Handler = std::function<HttpResponse(const HttpRequest&)>;
  /// Binds and starts serving; throws std::runtime_error when the address/port cannot be bound.
  HttpServer(const std::string& address, std::uint16_t port, Handler handler);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;
  /// The bound port (useful with port 0).
  std::uint16_t port() const { return port_; }

 private:
  void accept();
  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
  Handler handler_;
  std::uint16_t port_ = 0;
  std::thread thread_;
};

/// True for 127.0.0.0/8 and ::1.
bool is_loopback_address(const std::string& address);

}  // namespace rgbdquad::quadcontrol
