// Beast HTTP server: see http_server.hpp.
#include "app/http_server.hpp"

#include <memory>
#include <optional>
#include <stdexcept>

#include <boost/asio/ip/address.hpp>
#include <boost/beast/core.hpp>

namespace rgbdquad::quadcontrol {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

namespace {
constexpr auto kIdleTimeout = std::chrono::seconds(30);  // browsers keep connections; free idle ones
constexpr std::size_t kMaxBodyBytes = 64 * 1024;          // the API's JSON bodies are tiny

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket socket, const HttpServer::Handler& handler) : stream_(std::move(socket)), handler_(handler) {}
  void run() { read(); }

 private:
  void read() {
    parser_.emplace();
    parser_->body_limit(kMaxBodyBytes);
    stream_.expires_after(kIdleTimeout);
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }
  void on_read(beast::error_code ec) {
    if (ec) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    const HttpRequest request = parser_->release();
    HttpResponse response;
    try {
      response = handler_(request);
    } catch (const std::exception& e) {  // nothing escapes the I/O thread
      response = HttpResponse{http::status::internal_server_error, request.version()};
      response.set(http::field::content_type, "text/plain");
      response.body() = std::string("internal error: ") + e.what();
    }
    response.keep_alive(request.keep_alive());
    response.prepare_payload();
    response_ = std::make_shared<HttpResponse>(std::move(response));
    http::async_write(stream_, *response_, [self = shared_from_this()](beast::error_code ec2, std::size_t) {
      if (ec2) return;
      if (!self->response_->keep_alive()) {
        beast::error_code ignored;
        self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
        return;
      }
      self->read();
    });
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<HttpResponse> response_;
  const HttpServer::Handler& handler_;
};
}  // namespace

bool is_loopback_address(const std::string& address) {
  beast::error_code ec;
  const auto a = asio::ip::make_address(address, ec);
  return !ec && a.is_loopback();
}

HttpServer::HttpServer(const std::string& address, std::uint16_t port, Handler handler)
    : acceptor_(io_), handler_(std::move(handler)) {
  beast::error_code ec;
  const auto addr = asio::ip::make_address(address, ec);
  if (ec) throw std::runtime_error("dashboard: not an IP address: '" + address + "'");
  const tcp::endpoint endpoint(addr, port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) throw std::runtime_error("dashboard: cannot listen on " + address + ":" + std::to_string(port) + ": " + ec.message());
  port_ = acceptor_.local_endpoint().port();
  accept();
  thread_ = std::thread([this] { io_.run(); });
}

HttpServer::~HttpServer() {
  io_.stop();
  if (thread_.joinable()) thread_.join();
}

void HttpServer::accept() {
  acceptor_.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (!ec) std::make_shared<Session>(std::move(socket), handler_)->run();
    if (acceptor_.is_open()) accept();
  });
}

}  // namespace rgbdquad::quadcontrol
