// Dashboard routes: see dashboard_api.hpp.
#include "app/dashboard_api.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace rgbdquad::quadcontrol {

namespace http = boost::beast::http;

namespace {
constexpr std::size_t kDefaultCloudPoints = 6000;  // ~200 KB of JSON: smooth in a canvas at 2 Hz
constexpr std::size_t kMaxCloudPoints = 50000;

std::string content_type_for(const std::string& name) {
  const auto ext = std::filesystem::path(name).extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".png") return "image/png";
  if (ext == ".svg") return "image/svg+xml";
  return "application/octet-stream";
}

HttpResponse make(const HttpRequest& req, http::status status, const std::string& type,
                  std::string body) {
  HttpResponse res{status, req.version()};
  res.set(http::field::content_type, type);
  res.set(http::field::cache_control, "no-store");
  res.body() = std::move(body);
  return res;
}

HttpResponse json_reply(const HttpRequest& req, const nlohmann::json& j,
                        http::status status = http::status::ok) {
  return make(req, status, "application/json", j.dump());
}

HttpResponse result_reply(const HttpRequest& req, const std::string& error) {
  if (error.empty()) return json_reply(req, {{"ok", true}});
  return json_reply(req, {{"ok", false}, {"error", error}}, http::status::conflict);
}

std::optional<OperatorCommand> operator_command_named(const std::string& name) {
  for (const OperatorCommand c : {OperatorCommand::kArm, OperatorCommand::kDisarm,
                                  OperatorCommand::kTakeOff, OperatorCommand::kLand}) {
    if (name == to_string(c)) return c;
  }
  return std::nullopt;
}

bool number(const nlohmann::json& j, const char* key, double* out) {
  if (!j.contains(key)) {
    *out = 0.0;
    return true;
  }
  if (!j[key].is_number()) return false;
  *out = j[key].get<double>();
  return std::isfinite(*out);
}
}  // namespace

DashboardApi::DashboardApi(DashboardBackend& station, const std::string& static_dir,
                           AccessPolicy policy, std::function<std::int64_t()> now_us)
    : station_(station), policy_(std::move(policy)), now_us_(std::move(now_us)) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(static_dir, ec))
    throw std::runtime_error("dashboard static dir not found: " + static_dir);
  for (const auto& entry : fs::directory_iterator(static_dir)) {
    if (!entry.is_regular_file()) continue;
    std::ifstream in(entry.path(), std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    const std::string name = entry.path().filename().string();
    files_["/" + name] = {content_type_for(name), bytes.str()};
  }
  if (!files_.count("/index.html"))
    throw std::runtime_error("dashboard: " + static_dir + "/index.html missing");
  files_["/"] = files_["/index.html"];
}

HttpResponse DashboardApi::handle(const HttpRequest& req) {
  const std::string target(req.target());
  const std::string path = target.substr(0, target.find('?'));
  if (path.rfind("/api/", 0) != 0) {
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      return make(req, http::status::method_not_allowed, "text/plain", "GET only\n");
    }
    const auto it = files_.find(path);
    if (it == files_.end()) return make(req, http::status::not_found, "text/plain", "not found\n");
    return make(req, http::status::ok, it->second.first, it->second.second);
  }
  if (const auto refusal = check_api_request(req, policy_)) {
    return json_reply(req, {{"ok", false}, {"error", refusal->reason}}, refusal->status);
  }
  const bool get = req.method() == http::verb::get;
  const bool post = req.method() == http::verb::post;
  if (get && path == "/api/state") return json_reply(req, station_.state_json(now_us_()));
  if (get && path == "/api/rgb.jpg") {
    auto jpg = station_.rgb_jpeg();
    if (!jpg) return make(req, http::status::service_unavailable, "text/plain", "no frame yet\n");
    return make(req, http::status::ok, "image/jpeg", std::move(*jpg));
  }
  if (get && path == "/api/depth.png") {
    auto png = station_.depth_png();
    if (!png) return make(req, http::status::service_unavailable, "text/plain", "no frame yet\n");
    return make(req, http::status::ok, "image/png", std::move(*png));
  }
  if (get && path == "/api/map.png")
    return make(req, http::status::ok, "image/png", station_.map_png());
  if (get && path == "/api/map.ply") {
    auto res = make(req, http::status::ok, "application/octet-stream", station_.map_ply());
    res.set(http::field::content_disposition, "attachment; filename=\"quad-control-map.ply\"");
    return res;
  }
  if (get && path == "/api/cloud") {
    std::size_t max_points = kDefaultCloudPoints;
    const std::string m = query_param(target, "max");
    if (!m.empty()) {
      char* end = nullptr;
      const long v = std::strtol(m.c_str(), &end, 10);
      if (end == m.c_str() || *end != '\0' || v < 1) {
        return json_reply(req, {{"ok", false}, {"error", "max must be a positive integer"}},
                          http::status::bad_request);
      }
      max_points = std::min<std::size_t>(static_cast<std::size_t>(v), kMaxCloudPoints);
    }
    return json_reply(req, station_.cloud_json(max_points));
  }
  if (post && (path == "/api/command" || path == "/api/waypoint" || path == "/api/manual" ||
               path == "/api/manoeuvre")) {
    const auto body = nlohmann::json::parse(req.body(), nullptr, false);
    if (body.is_discarded() || !body.is_object()) {
      return json_reply(req, {{"ok", false}, {"error", "body must be a JSON object"}},
                        http::status::bad_request);
    }
    if (path == "/api/command") {
      if (!body.contains("command") || !body["command"].is_string()) {
        return json_reply(req, {{"ok", false}, {"error", "expected {\"command\": \"arm\"|...}"}},
                          http::status::bad_request);
      }
      const std::string name = body["command"].get<std::string>();
      const auto command = operator_command_named(name);
      if (!command)
        return result_reply(req, "unknown command '" + name + "' (arm, disarm, takeoff, land)");
      return result_reply(req, station_.command(now_us_(), *command));
    }
    if (path == "/api/waypoint") {
      double x, y;
      if (!body.contains("x_m") || !body.contains("y_m") || !number(body, "x_m", &x) ||
          !number(body, "y_m", &y)) {
        return json_reply(req, {{"ok", false}, {"error", "expected finite numbers x_m, y_m"}},
                          http::status::bad_request);
      }
      return result_reply(req, station_.waypoint(now_us_(), x, y));
    }
    if (path == "/api/manoeuvre") {
      ManoeuvreRequest r;
      if (!number(body, "forward_m", &r.forward_m) || !number(body, "left_m", &r.left_m) ||
          !number(body, "yaw_ccw_deg", &r.yaw_ccw_deg) ||
          !number(body, "speed_m_per_s", &r.speed_m_per_s) ||
          !number(body, "yaw_rate_deg_per_s", &r.yaw_rate_deg_per_s)) {
        return json_reply(req,
                          {{"ok", false}, {"error", "manoeuvre values must be finite numbers"}},
                          http::status::bad_request);
      }
      return result_reply(req, station_.manoeuvre(now_us_(), r));
    }
    double f, l, u, yaw;
    if (!number(body, "forward_m", &f) || !number(body, "left_m", &l) ||
        !number(body, "up_m", &u) || !number(body, "yaw_ccw_deg", &yaw)) {
      return json_reply(req, {{"ok", false}, {"error", "manual steps must be finite numbers"}},
                        http::status::bad_request);
    }
    return result_reply(req, station_.manual(now_us_(), f, l, u, yaw));
  }
  return json_reply(req, {{"ok", false}, {"error", "no such API route"}}, http::status::not_found);
}

}  // namespace rgbdquad::quadcontrol
