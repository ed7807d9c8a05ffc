// Dashboard API access checks: a foreign page or a DNS-rebinding host must
// not command the craft; the dashboard page itself and non-browser clients must. Table-driven.
#include "app/request_guard.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace rgbdquad::quadcontrol {
namespace {

namespace http = boost::beast::http;

struct Row {
  const char* name;
  http::verb method;
  const char* target;
  std::vector<std::pair<const char*, const char*>> headers;
  std::optional<http::status> refused;  // nullopt: accepted
  unsigned http_version = 11;           // 10: an HTTP/1.0 client (Host optional)
};

HttpRequest make_request(const Row& row) {
  HttpRequest req{row.method, row.target, row.http_version};
  for (const auto& [k, v] : row.headers) req.set(k, v);
  req.body() = R"({"command":"arm"})";
  req.prepare_payload();
  return req;
}

void run_table(const std::vector<Row>& table, const AccessPolicy& policy) {
  for (const auto& row : table) {
    SCOPED_TRACE(row.name);
    const auto refusal = check_api_request(make_request(row), policy);
    ASSERT_EQ(refusal.has_value(), row.refused.has_value())
        << (refusal ? refusal->reason : "accepted");
    if (refusal) {
      EXPECT_EQ(refusal->status, *row.refused);
      EXPECT_FALSE(refusal->reason.empty());
    }
  }
}

constexpr auto kPost = http::verb::post;
constexpr auto kGet = http::verb::get;
const char* const kJson = "application/json";

TEST(RequestGuard, CrossSiteProbesWithoutToken) {
  const std::vector<Row> table = {
      // the dashboard page itself (Chromium): same origin, JSON
      {"page POST",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"},
        {"Origin", "http://127.0.0.1:8080"},
        {"Sec-Fetch-Site", "same-origin"},
        {"Content-Type", "application/json"}},
       std::nullopt},
      {"page GET",
       kGet,
       "/api/state",
       {{"Host", "127.0.0.1:8080"}, {"Sec-Fetch-Site", "same-origin"}},
       std::nullopt},
      {"typed URL",
       kGet,
       "/api/state",
       {{"Host", "localhost:8080"}, {"Sec-Fetch-Site", "none"}},
       std::nullopt},
      {"IPv6 loopback",
       kPost,
       "/api/command",
       {{"Host", "[::1]:8080"}, {"Origin", "http://[::1]:8080"}, {"Content-Type", kJson}},
       std::nullopt},
      {"JSON with charset",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Content-Type", "application/json; charset=utf-8"}},
       std::nullopt},
      // non-browser clients (curl, the HIL rig): no Origin
      {"HIL rig POST",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Content-Type", kJson}},
       std::nullopt},
      {"no Host (HTTP/1.0 client)",
       kPost,
       "/api/command",
       {{"Content-Type", kJson}},
       std::nullopt,
       10},
      {"no Host (HTTP/1.1 requires one)",
       kPost,
       "/api/command",
       {{"Content-Type", kJson}},
       http::status::bad_request},
      // the issue's probe: text/plain from evil.example through a rebinding host name
      {"issue probe",
       kPost,
       "/api/command",
       {{"Host", "evil.example:8080"},
        {"Origin", "http://evil.example"},
        {"Content-Type", "text/plain"}},
       http::status::forbidden},
      {"Origin evil.example",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Origin", "http://evil.example"}, {"Content-Type", kJson}},
       http::status::forbidden},
      {"Origin null (sandboxed frame, file://)",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Origin", "null"}, {"Content-Type", kJson}},
       http::status::forbidden},
      {"Origin other port",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Origin", "http://127.0.0.1:9999"}, {"Content-Type", kJson}},
       http::status::forbidden},
      {"Host evil.example (DNS rebinding, same-origin to the browser)",
       kPost,
       "/api/command",
       {{"Host", "evil.example:8080"},
        {"Origin", "http://evil.example:8080"},
        {"Content-Type", kJson}},
       http::status::forbidden},
      {"Host evil.example GET state",
       kGet,
       "/api/state",
       {{"Host", "evil.example:8080"}},
       http::status::forbidden},
      {"Host localhost.evil.example",
       kGet,
       "/api/state",
       {{"Host", "localhost.evil.example"}},
       http::status::forbidden},
      {"text/plain (simple request)",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Content-Type", "text/plain"}},
       http::status::unsupported_media_type},
      {"form (simple request)",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Content-Type", "application/x-www-form-urlencoded"}},
       http::status::unsupported_media_type},
      {"multipart (simple request)",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Content-Type", "multipart/form-data; boundary=x"}},
       http::status::unsupported_media_type},
      {"no Content-Type",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}},
       http::status::unsupported_media_type},
      {"json lookalike",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Content-Type", "application/jsonx"}},
       http::status::unsupported_media_type},
      {"Sec-Fetch-Site cross-site",
       kPost,
       "/api/command",
       {{"Host", "127.0.0.1:8080"}, {"Sec-Fetch-Site", "cross-site"}, {"Content-Type", kJson}},
       http::status::forbidden},
      {"Sec-Fetch-Site same-site",
       kGet,
       "/api/state",
       {{"Host", "127.0.0.1:8080"}, {"Sec-Fetch-Site", "same-site"}},
       http::status::forbidden},
  };
  run_table(table, AccessPolicy{});
}

TEST(RequestGuard, AllowedHostsAndToken) {
  const AccessPolicy policy{"0123456789abcdef0123456789abcdef", {"GroundStation.local"}};
  const std::vector<Row> table = {
      {"configured host name, token header",
       kPost,
       "/api/command",
       {{"Host", "groundstation.local:8080"},
        {"Origin", "http://groundstation.local:8080"},
        {"Content-Type", kJson},
        {"X-Dashboard-Token", "0123456789abcdef0123456789abcdef"}},
       std::nullopt},
      {"token in the query (images)",
       kGet,
       "/api/rgb.jpg?n=3&token=0123456789abcdef0123456789abcdef",
       {{"Host", "192.168.1.10:8080"}},
       std::nullopt},
      {"no token", kGet, "/api/state", {{"Host", "192.168.1.10:8080"}}, http::status::unauthorized},
      {"wrong token",
       kGet,
       "/api/state",
       {{"Host", "192.168.1.10:8080"}, {"X-Dashboard-Token", "0123"}},
       http::status::unauthorized},
      {"token prefix",
       kGet,
       "/api/state?token=0123456789abcdef0123456789abcde",
       {{"Host", "192.168.1.10"}},
       http::status::unauthorized},
      {"right token, foreign Origin",
       kPost,
       "/api/command",
       {{"Host", "192.168.1.10:8080"},
        {"Origin", "http://evil.example"},
        {"Content-Type", kJson},
        {"X-Dashboard-Token", "0123456789abcdef0123456789abcdef"}},
       http::status::forbidden},
  };
  run_table(table, policy);
}

TEST(RequestGuard, HostWithoutPort) {
  EXPECT_EQ(host_without_port("127.0.0.1:8080"), "127.0.0.1");
  EXPECT_EQ(host_without_port("[::1]:8080"), "::1");
  EXPECT_EQ(host_without_port("Evil.Example"), "evil.example");
  EXPECT_EQ(host_without_port("::1"), "::1");
}

TEST(RequestGuard, TokenStrengthForPublicBinds) {
  const struct {
    const char* token;
    bool ok;
  } table[] = {
      {"", false},
      {"x", false},
      {"s3cret", false},
      {"aaaaaaaaaaaaaaaaaaaaaaaa", false},  // long but one character
      {"abababababababababab", false},
      {"0123456789abcdef", true},                  // 16 distinct
      {"9f86d081884c7d659a2feaa0c55ad015", true},  // openssl rand -hex 16
  };
  for (const auto& row : table) {
    SCOPED_TRACE(row.token);
    EXPECT_EQ(check_token_strength(row.token).empty(), row.ok);
  }
}

TEST(QueryParam, GivenATargetWhenAParameterIsAskedThenItsRawValueOrEmptyComesBack) {
  EXPECT_EQ(query_param("/api/cloud?max=500&token=abc", "max"), "500");
  EXPECT_EQ(query_param("/api/cloud?max=500&token=abc", "token"), "abc");
  EXPECT_EQ(query_param("/api/cloud?flag&max=1", "flag"), "");
  EXPECT_EQ(query_param("/api/cloud?max=1", "token"), "");
  EXPECT_EQ(query_param("/api/cloud", "max"), "");
  EXPECT_EQ(query_param("/api/cloud?maximum=9", "max"), "");
}

}  // namespace
}  // namespace rgbdquad::quadcontrol
