// Who may use the dashboard API: the checks every /api/ request passes before a route runs
// (without them a foreign web page, or a DNS-rebinding host, could arm the craft).
//
// A browser lets any page send a "simple" cross-site POST (Content-Type text/plain, form types)
// to 127.0.0.1 without asking the server first, and a DNS-rebinding host name makes a foreign
// page same-origin with us. So, for every /api/ request:
//   1. Host must name this server: an IP literal, "localhost", or one of `allowed_hosts` (a
//      rebinding attack always arrives with the attacker's host name) -> else 403;
//   2. Origin, when the browser sends one, must be http://<Host> (same origin) -> else 403;
//      Sec-Fetch-Site, when sent, must be "same-origin" or "none" (typed URL) -> else 403;
//   3. anything but GET/HEAD must be Content-Type application/json: a browser sends that
//      cross-site only after a CORS preflight, which this server never grants -> else 415;
//   4. with a token configured it must be given (X-Dashboard-Token header or ?token=), compared
//      in constant time -> else 401.
// Clients that are not browsers (curl, the HIL rig, tests) send no Origin and pass with a JSON
// body. Pure functions, thread-safe.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "app/http_server.hpp"

namespace rgbdquad::quadcontrol {

struct AccessPolicy {
  std::string token;  ///< empty: no token asked (loopback binds only)
  std::vector<std::string>
      allowed_hosts;  ///< host names accepted in Host besides IP literals and localhost
};

struct Refusal {
  boost::beast::http::status status;
  std::string reason;
};

/// nullopt when `request` (to an /api/ route) may proceed, else why not.
std::optional<Refusal> check_api_request(const HttpRequest& request, const AccessPolicy& policy);

/// The raw (not percent-decoded) value of query parameter `name` in a request target
/// ("/api/x?a=1&b" -> "1" for "a", "" for "b"); empty when absent. Pure, thread-safe.
std::string query_param(const std::string& target, const std::string& name);

/// The host part of a Host header value ("[::1]:8080" -> "::1", "Example:80" -> "example").
std::string host_without_port(const std::string& host_header);

/// Minimum strength of a dashboard token for a non-loopback bind: empty when `token` is
/// acceptable, else why not.
std::string check_token_strength(const std::string& token);

}  // namespace rgbdquad::quadcontrol
