// Beast HTTP server: see http_server.hpp.
#include "app/http_server.hpp"

#include <pthread.h>
#include <sys/resource.h>

#include <algorithm>
#include <boost/asio/ip/address.hpp>
#include <boost/beast/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>

#include "app/log_line.hpp"

namespace rgbdquad::quadcontrol {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;

namespace {
constexpr auto kIdleTimeout =
    std::chrono::seconds(30);                     // browsers keep connections; free idle ones
constexpr std::size_t kMaxBodyBytes = 64 * 1024;  // the API's JSON bodies are tiny
// Accept back-off: the first retry soon (a descriptor is often freed within milliseconds), then
// doubling to 1 s, which bounds both the wasted CPU (a few wake-ups per second) and the delay a
// real client sees once descriptors are free again.
constexpr auto kFirstBackoff = std::chrono::milliseconds(10);
constexpr auto kMaxBackoff = std::chrono::milliseconds(1000);
// Sessions: a browser opens up to 6 connections per host; the rest of the descriptors belong to
// the frame source, SLAM and firmware links.
constexpr std::size_t kMinSessions = 4;
constexpr std::size_t kMaxSessions = 256;

std::size_t sessions_for_fd_limit() {
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return kMaxSessions;
  return std::clamp<std::size_t>(static_cast<std::size_t>(limit.rlim_cur) / 4, kMinSessions,
                                 kMaxSessions);
}

bool is_parse_error(const beast::error_code& ec) {
  return ec.category() == http::make_error_code(http::error::bad_target).category() &&
         ec != http::error::end_of_stream && ec != http::error::partial_message;
}
}  // namespace

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, const HttpServer::Handler& handler)
      : stream_(std::move(socket)), handler_(handler) {}
  void run() { read(); }
  /// Waiting for the next request (no request being handled or answered).
  bool idle() const { return idle_; }
  Clock::time_point idle_since() const { return idle_since_; }
  void close() {
    beast::error_code ignored;
    stream_.socket().close(ignored);
  }

 private:
  void read() {
    parser_.emplace();
    parser_->body_limit(kMaxBodyBytes);
    stream_.expires_after(kIdleTimeout);
    idle_ = true;
    idle_since_ = Clock::now();
    http::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }
  void on_read(beast::error_code ec) {
    idle_ = false;
    if (ec) {
      if (is_parse_error(ec) && stream_.socket().is_open()) {
        // Say why before closing (a silent close looks like a network fault to the client).
        const bool too_big = ec == http::error::body_limit || ec == http::error::header_limit;
        HttpResponse res{too_big ? http::status::payload_too_large : http::status::bad_request, 11};
        res.set(http::field::content_type, "text/plain");
        res.body() = std::string("malformed request: ") + ec.message() + "\n";
        res.keep_alive(false);
        res.prepare_payload();
        respond(std::move(res));
        return;
      }
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
    respond(std::move(response));
  }
  void respond(HttpResponse response) {
    response_ = std::make_shared<HttpResponse>(std::move(response));
    stream_.expires_after(kIdleTimeout);
    http::async_write(stream_, *response_,
                      [self = shared_from_this()](beast::error_code ec2, std::size_t) {
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
  bool idle_ = false;
  Clock::time_point idle_since_ = Clock::now();
};

bool is_loopback_address(const std::string& address) {
  beast::error_code ec;
  const auto a = asio::ip::make_address(address, ec);
  return !ec && a.is_loopback();
}

HttpServer::HttpServer(const std::string& address, std::uint16_t port, Handler handler,
                       std::size_t max_sessions)
    : acceptor_(io_),
      retry_timer_(io_),
      handler_(std::move(handler)),
      max_sessions_(max_sessions > 0 ? max_sessions : sessions_for_fd_limit()) {
  beast::error_code ec;
  const auto addr = asio::ip::make_address(address, ec);
  if (ec) throw std::runtime_error("dashboard: not an IP address: '" + address + "'");
  const tcp::endpoint endpoint(addr, port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    throw std::runtime_error("dashboard: cannot listen on " + address + ":" + std::to_string(port) +
                             ": " + ec.message());
  port_ = acceptor_.local_endpoint().port();
  accept();
  thread_ = std::thread([this] { io_.run(); });
  pthread_setname_np(thread_.native_handle(),
                     "qc-dashboard");  // found by name in /proc (tests, top -H)
}

HttpServer::~HttpServer() {
  io_.stop();
  if (thread_.joinable()) thread_.join();
}

void HttpServer::evict_idlest() {
  sessions_.remove_if([](const std::weak_ptr<HttpSession>& w) { return w.expired(); });
  if (sessions_.size() < max_sessions_) return;
  std::shared_ptr<HttpSession> idlest;
  for (const auto& w : sessions_) {
    auto s = w.lock();
    if (s && s->idle() && (!idlest || s->idle_since() < idlest->idle_since())) idlest = s;
  }
  if (idlest) idlest->close();  // its pending read ends with operation_aborted; the session goes
}

void HttpServer::on_accept_error(const boost::system::error_code& ec) {
  ++failed_accepts_;
  if (backoff_.count() == 0) {
    backoff_ = kFirstBackoff;
    log_line("dashboard: accept failed (" + ec.message() + "); backing off up to " +
             std::to_string(kMaxBackoff.count()) + " ms between retries");
  } else {
    backoff_ = std::min(backoff_ * 2, std::chrono::milliseconds(kMaxBackoff));
  }
  retry_timer_.expires_after(backoff_);
  retry_timer_.async_wait([this](const boost::system::error_code& timer_ec) {
    if (!timer_ec && acceptor_.is_open()) accept();
  });
}

void HttpServer::accept() {
  acceptor_.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor_.is_open()) return;
    if (ec) {
      // EMFILE/ENFILE/ENOBUFS/ENOMEM and the like: the pending connection stays in the backlog and
      // an immediate retry fails the same way, so wait before the next one.
      on_accept_error(ec);
      return;
    }
    if (backoff_.count() != 0) {
      log_line("dashboard: accepting again after " + std::to_string(failed_accepts_) +
               " failed accepts");
      backoff_ = std::chrono::milliseconds(0);
      failed_accepts_ = 0;
    }
    evict_idlest();
    auto session = std::make_shared<HttpSession>(std::move(socket), handler_);
    sessions_.push_back(session);
    session->run();
    accept();
  });
}

}  // namespace rgbdquad::quadcontrol
