// libFuzzer target: quad-control's dashboard request path without sockets - the bytes of one
// HTTP request through the Boost.Beast parser with the server's limits (http_server.cpp), then
// the API guard (request_guard.hpp) under three policies: loopback without a token, a token,
// allowed host names. Properties (abort on violation): no crash/UB; a request the guard lets
// through is one a browser cannot send cross-site: its Host (when present; only non-browser
// clients omit it, and then without Origin) is an IP literal, localhost or an allowed name, any
// Origin equals http://<Host>, anything but GET/HEAD has no CORS-safelisted Content-Type; with a
// token configured, the token was given; refusals are 4xx with a reason.
#include <boost/asio/ip/address.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http.hpp>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "app/request_guard.hpp"

namespace {

namespace http = boost::beast::http;
using rgbdquad::quadcontrol::AccessPolicy;
using rgbdquad::quadcontrol::HttpRequest;

// The server's limits (http_server.cpp kMaxBodyBytes; Beast's default 8 KiB header limit).
constexpr std::uint64_t kMaxBodyBytes = 64 * 1024;

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// A Content-Type a browser may send cross-site without a CORS preflight (the Fetch standard's
// CORS-safelisted types), judged the way a browser parses it (essence before ';', trimmed).
bool cors_safelisted(const std::string& content_type) {
  std::string essence = lower(content_type.substr(0, content_type.find(';')));
  const auto first = essence.find_first_not_of(" \t");
  const auto last = essence.find_last_not_of(" \t");
  essence = first == std::string::npos ? "" : essence.substr(first, last - first + 1);
  return essence.empty() || essence == "text/plain" ||
         essence == "application/x-www-form-urlencoded" || essence == "multipart/form-data";
}

void check(const HttpRequest& req, const AccessPolicy& policy) {
  const auto refusal = rgbdquad::quadcontrol::check_api_request(req, policy);
  if (refusal) {
    const int code = static_cast<int>(refusal->status);
    if (code < 400 || code > 499 || refusal->reason.empty()) std::abort();
    return;
  }
  const std::string host_header(req[http::field::host]);
  const std::string origin(
      req[http::field::origin]);  // a browser's is never empty ("null" at least)
  if (host_header.empty()) {
    // Without Host only a non-browser client (browsers always send it, with Origin on a POST)
    if (!origin.empty()) std::abort();
  } else {
    const std::string host = rgbdquad::quadcontrol::host_without_port(host_header);
    // An IP literal (IPv4, IPv6, IPv6 with a zone id such as [fe80::1%eth0]) cannot be a
    // rebinding host name, so any of them is fine; the standard parser decides what is one.
    boost::system::error_code ec;
    boost::asio::ip::make_address(host, ec);
    const bool known =
        host == "localhost" || host == "groundstation.local" || host == "quad" || !ec;
    if (!known) std::abort();
    if (!origin.empty() && lower(origin) != "http://" + lower(host_header)) std::abort();
  }
  if (req.method() != http::verb::get && req.method() != http::verb::head &&
      cors_safelisted(std::string(req[http::field::content_type]))) {
    std::abort();  // a "simple" cross-site request would have got through
  }
  if (!policy.token.empty()) {
    const std::string target(req.target());
    if (req.find("X-Dashboard-Token") == req.end() && target.find("token=") == std::string::npos)
      std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  http::request_parser<http::string_body> parser;
  parser.body_limit(kMaxBodyBytes);
  parser.eager(true);
  boost::beast::error_code ec;
  std::size_t used = parser.put(boost::asio::buffer(data, size), ec);
  if (!ec && !parser.is_done()) {
    parser.put_eof(ec);
  }
  (void)used;
  if (ec || !parser.is_done()) return 0;
  const HttpRequest& req = parser.get();
  static const AccessPolicy open{};
  static const AccessPolicy with_token{"0123456789abcdef0123", {}};
  static const AccessPolicy named{"", {"groundstation.local", "quad"}};
  check(req, open);
  check(req, with_token);
  check(req, named);
  return 0;
}
