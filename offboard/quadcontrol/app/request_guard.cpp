// Dashboard API access checks: see request_guard.hpp.
#include "app/request_guard.hpp"

#include <algorithm>
#include <boost/asio/ip/address.hpp>
#include <cctype>
#include <set>
#include <sstream>

namespace rgbdquad::quadcontrol {

namespace http = boost::beast::http;

namespace {
// A token guessed online at even 10^4 requests/s must take years: 16 characters from a random
// hex/base64 generator (`openssl rand -hex 16` gives 32) are 64+ bits. Few distinct characters
// ("aaaaaaaaaaaaaaaa", "abababab...") are not random.
constexpr std::size_t kMinTokenChars = 16;
constexpr std::size_t kMinDistinctTokenChars = 8;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string header(const HttpRequest& req, boost::beast::string_view name) {
  const auto it = req.find(name);
  return it == req.end() ? std::string() : std::string(it->value());
}

bool equal_constant_time(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

bool is_ip_literal(const std::string& host) {
  boost::system::error_code ec;
  boost::asio::ip::make_address(host, ec);
  return !ec;
}
}  // namespace

std::string query_param(const std::string& target, const std::string& name) {
  const auto q = target.find('?');
  if (q == std::string::npos) return {};
  std::istringstream in(target.substr(q + 1));
  std::string pair;
  while (std::getline(in, pair, '&')) {
    const auto eq = pair.find('=');
    if (pair.substr(0, eq) == name) return eq == std::string::npos ? "" : pair.substr(eq + 1);
  }
  return {};
}

std::string host_without_port(const std::string& host_header) {
  std::string h = lower(host_header);
  if (!h.empty() && h.front() == '[') {  // [v6]:port
    const auto end = h.find(']');
    return end == std::string::npos ? h : h.substr(1, end - 1);
  }
  const auto colon = h.find(':');
  if (colon != std::string::npos && h.find(':', colon + 1) == std::string::npos)
    h = h.substr(0, colon);
  return h;
}

std::optional<Refusal> check_api_request(const HttpRequest& req, const AccessPolicy& policy) {
  const std::string host_header = header(req, "Host");
  if (host_header.empty() && req.version() >= 11) {
    return Refusal{http::status::bad_request,
                   "HTTP/1.1 request without a Host header (RFC 9112 section 3.2)"};
  }
  if (!host_header.empty()) {
    const std::string host = host_without_port(host_header);
    const bool known = is_ip_literal(host) || host == "localhost" ||
                       std::any_of(policy.allowed_hosts.begin(), policy.allowed_hosts.end(),
                                   [&](const std::string& a) { return lower(a) == host; });
    if (!known)
      return Refusal{http::status::forbidden,
                     "Host '" + host_header + "' is not this server (dashboard.allowed_hosts)"};
  }
  const std::string origin = header(req, "Origin");
  if (!origin.empty() && lower(origin) != "http://" + lower(host_header)) {
    return Refusal{http::status::forbidden, "cross-origin request refused (Origin " + origin + ")"};
  }
  const std::string fetch_site = lower(header(req, "Sec-Fetch-Site"));
  if (!fetch_site.empty() && fetch_site != "same-origin" && fetch_site != "none") {
    return Refusal{http::status::forbidden,
                   "cross-site request refused (Sec-Fetch-Site " + fetch_site + ")"};
  }
  if (req.method() != http::verb::get && req.method() != http::verb::head) {
    std::string type = lower(header(req, "Content-Type"));
    type = type.substr(0, type.find(';'));
    type.erase(std::remove(type.begin(), type.end(), ' '), type.end());
    if (type != "application/json") {
      return Refusal{http::status::unsupported_media_type, "Content-Type must be application/json"};
    }
  }
  if (!policy.token.empty()) {
    const std::string from_header = header(req, "X-Dashboard-Token");
    const std::string given =
        !from_header.empty() ? from_header : query_param(std::string(req.target()), "token");
    if (!equal_constant_time(given, policy.token))
      return Refusal{http::status::unauthorized, "missing or wrong token"};
  }
  return std::nullopt;
}

std::string check_token_strength(const std::string& token) {
  if (token.size() < kMinTokenChars) {
    return "token too short: at least " + std::to_string(kMinTokenChars) +
           " characters for a non-loopback bind (e.g. `openssl rand -hex 16`)";
  }
  if (std::set<char>(token.begin(), token.end()).size() < kMinDistinctTokenChars) {
    return "token not random enough: fewer than " + std::to_string(kMinDistinctTokenChars) +
           " distinct characters";
  }
  return {};
}

}  // namespace rgbdquad::quadcontrol
