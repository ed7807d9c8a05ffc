// libFuzzer target: quad-control's dashboard routes (DashboardApi::handle) behind the request
// guard, backed by a real FlightController (the same core the GroundStation runs) through the
// DashboardBackend seam, without threads, sockets or a camera. One input is a flight: a sequence
// of steps, each either a pose estimate + control step at an advancing time (values from a
// hostile table: NaN, +-inf, +-1e308, huge, or near the setpoint so the craft really arms, takes
// off and holds) or one HTTP request (method, route, query, headers and body built from the input;
// JSON bodies with the routes' keys and hostile numbers, or raw bytes).
// Properties (abort on violation), after every step:
//   * replies are well-formed: a known status, a Content-Type, Cache-Control: no-store; /api/
//     replies are JSON objects with "ok" (true exactly on 200 for POST), an error text when not ok;
//   * a request that is not answered 200, and every GET, leaves the controller untouched (state,
//     setpoint, waypoint);
//   * the flight envelope is never left: setpoint (x, y, z, yaw) finite; z in [0, max_height_m];
//     in take-off / hold / go-to / lost-hold within max_distance_from_home_m of home (hold and
//     go-to also at or above min height); a waypoint finite and inside the fence; the stick
//     command finite, roll/pitch/yaw in [-100, 100] %, throttle in [0, 100] %;
//   * the cloud route never asks the backend for more than its 50000-point cap or fewer than 1.
#include <fuzzer/FuzzedDataProvider.h>
#include <unistd.h>

#include <algorithm>
#include <boost/beast/http.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "app/dashboard_api.hpp"
#include "app/dashboard_backend.hpp"
#include "core/control_config.hpp"
#include "core/flight_controller.hpp"

namespace {

namespace http = boost::beast::http;
using namespace rgbdquad::quadcontrol;

constexpr double kTolerance_m = 1e-9;             // rounding of the envelope's clamping
constexpr std::size_t kMaxCloudPoints = 50000;    // dashboard_api.cpp's cap
constexpr std::int64_t kMaxStepUs = 3'500'000;    // > arm_gesture_ms: a flight can really start
constexpr std::int64_t kFramePeriodUs = 100'000;  // 10 Hz poses and slower
constexpr int kMaxSteps = 64;

void require(bool ok) {
  if (!ok) std::abort();
}

/// The dashboard's backend with the real controller inside, time driven by the fuzzer.
class ControllerBackend final : public DashboardBackend {
 public:
  explicit ControllerBackend(const ControlConfig& config) : controller_(config) {}

  FlightController& controller() { return controller_; }
  std::int64_t now_us = 1'000'000;
  std::size_t last_cloud_request = 0;
  bool have_frame = false;

  nlohmann::json state_json(std::int64_t /*now_us*/) override {
    const ControllerStatus& st = controller_.status();
    return {{"state", to_string(st.state)},
            {"last_event", st.last_event},
            {"setpoint", {st.setpoint.x_m, st.setpoint.y_m, st.setpoint.z_m, st.setpoint.yaw_deg}}};
  }
  std::optional<std::string> rgb_jpeg() override {
    if (!have_frame) return std::nullopt;
    return std::string("\xff\xd8\xff\xd9", 4);
  }
  std::optional<std::string> depth_png() override {
    if (!have_frame) return std::nullopt;
    return std::string("\x89PNG", 4);
  }
  std::string map_png() override { return std::string("\x89PNG", 4); }
  nlohmann::json cloud_json(std::size_t max_points) override {
    last_cloud_request = max_points;
    return nlohmann::json::array();
  }
  std::string map_ply() override { return "ply\nformat ascii 1.0\nelement vertex 0\nend_header\n"; }
  std::string command(std::int64_t t_us, OperatorCommand command) override {
    return controller_.command(t_us, command);
  }
  std::string waypoint(std::int64_t t_us, double x_m, double y_m) override {
    return controller_.set_waypoint(t_us, x_m, y_m);
  }
  std::string manual(std::int64_t t_us, double forward_m, double left_m, double up_m,
                     double yaw_ccw_deg) override {
    return controller_.nudge(t_us, forward_m, left_m, up_m, yaw_ccw_deg);
  }

 private:
  FlightController controller_;
};

/// What a refused request must not change.
struct Snapshot {
  FlightState state;
  CraftPose setpoint;
  std::optional<Waypoint> waypoint;
};

Snapshot snapshot(const FlightController& c) {
  const ControllerStatus& st = c.status();
  return {st.state, st.setpoint, st.waypoint};
}

bool same_double(double a, double b) {  // bit-for-bit, NaN equal to itself
  return std::memcmp(&a, &b, sizeof a) == 0;
}

bool same(const Snapshot& a, const Snapshot& b) {
  if (a.state != b.state || a.waypoint.has_value() != b.waypoint.has_value()) return false;
  if (a.waypoint && (!same_double(a.waypoint->x_m, b.waypoint->x_m) ||
                     !same_double(a.waypoint->y_m, b.waypoint->y_m)))
    return false;
  return same_double(a.setpoint.x_m, b.setpoint.x_m) &&
         same_double(a.setpoint.y_m, b.setpoint.y_m) &&
         same_double(a.setpoint.z_m, b.setpoint.z_m) &&
         same_double(a.setpoint.yaw_deg, b.setpoint.yaw_deg);
}

void check_envelope(const FlightController& c) {
  const ControllerStatus& st = c.status();
  const EnvelopeLimits& limits = c.envelope().limits();
  const CraftPose& sp = st.setpoint;
  require(std::isfinite(sp.x_m) && std::isfinite(sp.y_m) && std::isfinite(sp.z_m) &&
          std::isfinite(sp.yaw_deg));
  require(sp.z_m >= 0.0 && sp.z_m <= limits.max_height_m + kTolerance_m);
  const auto& home = c.envelope().home();
  const FlightState s = st.state;
  const bool fenced = s == FlightState::kTakeOff || s == FlightState::kHold ||
                      s == FlightState::kGoToWaypoint || s == FlightState::kLostHold;
  if (fenced) {
    require(home.has_value());  // nothing flies before a take-off set home
    require(std::hypot(sp.x_m - home->x_m, sp.y_m - home->y_m) <=
            limits.max_distance_from_home_m + kTolerance_m);
  }
  if (s == FlightState::kHold || s == FlightState::kGoToWaypoint)
    require(sp.z_m >= limits.min_height_m - kTolerance_m);
  if (st.waypoint) {
    require(std::isfinite(st.waypoint->x_m) && std::isfinite(st.waypoint->y_m) && home.has_value());
    require(std::hypot(st.waypoint->x_m - home->x_m, st.waypoint->y_m - home->y_m) <=
            limits.max_distance_from_home_m + kTolerance_m);
  }
}

void check_stick(const StickCommand& cmd) {
  for (double v : {cmd.roll_pct, cmd.pitch_pct, cmd.yaw_pct})
    require(std::isfinite(v) && v >= -100.0 && v <= 100.0);
  require(std::isfinite(cmd.throttle_pct) && cmd.throttle_pct >= 0.0 && cmd.throttle_pct <= 100.0);
}

/// A value from the hostile table or a small number around `near`.
double hostile_double(FuzzedDataProvider& in, double near) {
  static const double kTable[] = {std::numeric_limits<double>::quiet_NaN(),
                                  std::numeric_limits<double>::infinity(),
                                  -std::numeric_limits<double>::infinity(),
                                  1e308,
                                  -1e308,
                                  std::numeric_limits<double>::max(),
                                  std::numeric_limits<double>::lowest(),
                                  std::numeric_limits<double>::denorm_min(),
                                  -0.0,
                                  50.0,
                                  -50.0,
                                  1e6};
  switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0:
      return kTable[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kTable) - 1)];
    case 1:
      return in.ConsumeFloatingPoint<double>();
    default:
      return near + in.ConsumeFloatingPointInRange<double>(-1.5, 1.5);
  }
}

/// A JSON number (or not) as text, hostile ones included ("1e400" overflows to inf in a parser).
std::string json_value(FuzzedDataProvider& in) {
  static const char* kTexts[] = {"0",
                                 "1",
                                 "-1",
                                 "0.5",
                                 "-0.25",
                                 "1e308",
                                 "-1e308",
                                 "1e400",
                                 "-1e400",
                                 "1e-400",
                                 "null",
                                 "true",
                                 "\"1\"",
                                 "[]",
                                 "{}",
                                 "99999999999999999999",
                                 "-0",
                                 "4.9e-324",
                                 "1.7976931348623157e308",
                                 "NaN",
                                 "Infinity",
                                 "0.1e1"};
  if (in.ConsumeBool())
    return kTexts[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kTexts) - 1)];
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", in.ConsumeFloatingPointInRange<double>(-6.0, 6.0));
  return buf;
}

std::string json_body(FuzzedDataProvider& in, const std::string& path) {
  static const char* kKeys[] = {"command", "x_m",         "y_m", "forward_m", "left_m",
                                "up_m",    "yaw_ccw_deg", "max", ""};
  static const char* kCommands[] = {"arm", "disarm", "takeoff", "land", "ARM", "", "arm ", "fly"};
  std::string body = "{";
  const int n = in.ConsumeIntegralInRange<int>(0, 5);
  for (int i = 0; i < n; ++i) {
    if (i) body += ",";
    std::string key = kKeys[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kKeys) - 1)];
    if (path == "/api/command" && in.ConsumeBool()) key = "command";
    body += "\"" + key + "\":";
    if (key == "command" && in.ConsumeBool()) {
      body += std::string("\"") +
              kCommands[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kCommands) - 1)] + "\"";
    } else {
      body += json_value(in);
    }
  }
  return body + "}";
}

/// A number near `centre` (within +-span), as JSON text: the values an operator really sends.
std::string near_value(FuzzedDataProvider& in, double centre, double span) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g",
                centre + in.ConsumeFloatingPointInRange<double>(-span, span));
  return buf;
}

/// A well-formed operator request (the dashboard page's): the right method, Host and Content-Type,
/// a body with the route's keys, values plausible or hostile.
std::string operator_body(FuzzedDataProvider& in, const FlightController& c, std::string* path) {
  static const char* kCommands[] = {"arm", "takeoff", "land", "disarm", "fly"};
  const CraftPose& sp = c.status().setpoint;
  const auto value = [&](double centre, double span) {
    return in.ConsumeIntegralInRange<int>(0, 3) == 0 ? json_value(in)
                                                     : near_value(in, centre, span);
  };
  switch (in.ConsumeIntegralInRange<int>(0, 2)) {
    case 0:
      *path = "/api/command";
      return std::string("{\"command\":\"") +
             kCommands[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kCommands) - 1)] + "\"}";
    case 1:
      *path = "/api/waypoint";
      return "{\"x_m\":" + value(sp.x_m, 8.0) + ",\"y_m\":" + value(sp.y_m, 8.0) + "}";
    default:
      *path = "/api/manual";
      return "{\"forward_m\":" + value(0.0, 1.5) + ",\"left_m\":" + value(0.0, 1.5) +
             ",\"up_m\":" + value(0.0, 1.5) + ",\"yaw_ccw_deg\":" + value(0.0, 120.0) + "}";
  }
}

http::verb pick_method(FuzzedDataProvider& in) {
  static const http::verb kVerbs[] = {http::verb::post, http::verb::get,     http::verb::head,
                                      http::verb::put,  http::verb::delete_, http::verb::options};
  return kVerbs[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kVerbs) - 1)];
}

std::string pick_target(FuzzedDataProvider& in, std::string* path) {
  static const char* kPaths[] = {
      "/api/command", "/api/waypoint",  "/api/manual",  "/api/state",   "/api/cloud",
      "/api/rgb.jpg", "/api/depth.png", "/api/map.png", "/api/map.ply", "/",
      "/index.html",  "/app.js",        "/api/",        "/api/nope",    "/../etc/passwd"};
  static const char* kQueries[] = {
      "",         "?max=10", "?max=0", "?max=-5",    "?max=99999999999999999999",
      "?max=1e3", "?max=",   "?max",   "?max=60000", "?a=1&max=3&max=4",
      "?token=x"};
  *path = kPaths[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kPaths) - 1)];
  if (in.ConsumeIntegralInRange<int>(0, 7) == 0) *path = in.ConsumeRandomLengthString(32);
  std::string query = kQueries[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kQueries) - 1)];
  if (in.ConsumeIntegralInRange<int>(0, 7) == 0) query = "?max=" + in.ConsumeRandomLengthString(24);
  return *path + query;
}

void check_reply(const HttpRequest& req, const HttpResponse& res, const std::string& path) {
  const int code = res.result_int();
  static const int kKnown[] = {200, 400, 403, 404, 405, 409, 415, 503};
  require(std::find(std::begin(kKnown), std::end(kKnown), code) != std::end(kKnown));
  require(!res[http::field::content_type].empty());
  require(res[http::field::cache_control] == "no-store");
  const std::string target(req.target());
  if (target.substr(0, target.find('?')).rfind("/api/", 0) != 0) return;
  const bool json = res[http::field::content_type] == "application/json";
  if (code == 200 && !json) return;  // images, PLY
  if (code == 503) return;           // "no frame yet" (text)
  require(json);
  const auto j = nlohmann::json::parse(res.body(), nullptr, false);
  require(!j.is_discarded());
  if (code == 200) {
    if (req.method() == http::verb::post) require(j.is_object() && j.value("ok", false) == true);
    (void)path;
    return;
  }
  require(j.is_object() && j.contains("ok") && j["ok"] == false);
  require(j.contains("error") && j["error"].is_string() && !j["error"].get<std::string>().empty());
}

const std::string& static_dir() {
  static const std::string dir = [] {
    const auto d =
        std::filesystem::temp_directory_path() / ("fuzz_dashboard_api_" + std::to_string(getpid()));
    std::filesystem::create_directories(d);
    std::ofstream(d / "index.html") << "<!doctype html><title>quad-control</title>\n";
    std::ofstream(d / "app.js") << "\"use strict\";\n";
    return d.string();
  }();
  return dir;
}

/// One request through the routes, with every reply and controller property checked.
void serve(DashboardApi& api, ControllerBackend& backend, const HttpRequest& req,
           const std::string& path) {
  FlightController& controller = backend.controller();
  const Snapshot before = snapshot(controller);
  const HttpResponse res = api.handle(req);
  check_reply(req, res, path);
  if (res.result_int() != 200 || req.method() != http::verb::post)
    require(same(before, snapshot(controller)));
  if (res.result_int() == 200 && path == "/api/cloud") {
    require(backend.last_cloud_request >= 1 && backend.last_cloud_request <= kMaxCloudPoints);
  }
  check_envelope(controller);
}

/// Time passes by `dt_us`; `pose` (if any) arrives; one control step runs.
void advance(ControllerBackend& backend, std::int64_t dt_us,
             const std::optional<PoseSample>& pose) {
  FlightController& controller = backend.controller();
  backend.now_us += dt_us;
  backend.have_frame = true;
  if (pose) {
    PoseSample sample = *pose;
    sample.received_us = backend.now_us;
    controller.on_pose(sample);
  }
  check_stick(controller.update(backend.now_us));
  check_envelope(controller);
}

HttpRequest operator_request(const std::string& path, const std::string& body) {
  HttpRequest req{http::verb::post, path, 11};
  req.set(http::field::host, "127.0.0.1:8080");
  req.set(http::field::content_type, "application/json");
  req.body() = body;
  req.prepare_payload();
  return req;
}

/// The operator's usual start, through the same routes: arm, wait out the arming gesture with the
/// craft resting at a fuzzed place, take off, climb with estimates on the setpoint until hold
/// (gives the rest of the input a flying craft to attack).
void fly_to_hold(DashboardApi& api, ControllerBackend& backend, FuzzedDataProvider& in) {
  // 10 Hz estimates (within pose_timeout_ms and the 0.5 m jump gate at 0.5 m/s): a third of the
  // control steps of 30 Hz, so the fuzzer spends its time on what follows.
  constexpr std::int64_t kPosePeriodUs = 100'000;
  constexpr std::int64_t kMaxClimbUs = 20'000'000;
  const FlightController& controller = backend.controller();
  PoseSample rest;
  rest.tracking = true;
  rest.pose = {in.ConsumeFloatingPointInRange<double>(-4.0, 4.0),
               in.ConsumeFloatingPointInRange<double>(-4.0, 4.0),
               in.ConsumeFloatingPointInRange<double>(0.0, 0.5),
               in.ConsumeFloatingPointInRange<double>(-180.0, 180.0)};
  serve(api, backend, operator_request("/api/command", R"({"command":"arm"})"), "/api/command");
  for (std::int64_t t = 0;
       t <= static_cast<std::int64_t>(controller.config().arm_gesture_ms) * 1000;
       t += kPosePeriodUs) {
    advance(backend, kPosePeriodUs, rest);
  }
  serve(api, backend, operator_request("/api/command", R"({"command":"takeoff"})"), "/api/command");
  for (std::int64_t t = 0; t < kMaxClimbUs && controller.status().state == FlightState::kTakeOff;
       t += kPosePeriodUs) {
    PoseSample on_setpoint = rest;
    const CraftPose& sp = controller.status().setpoint;
    on_setpoint.pose = {sp.x_m, sp.y_m, sp.z_m, sp.yaw_deg};
    advance(backend, kPosePeriodUs, on_setpoint);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  ControlConfig config;  // the shipped defaults (limits: 5 m from home, 3 m ceiling, 1 m steps)
  ControllerBackend backend(config);
  DashboardApi api(backend, static_dir(), AccessPolicy{}, [&backend] { return backend.now_us; });
  const FlightController& controller = backend.controller();

  for (int step = 0; step < kMaxSteps && in.remaining_bytes() > 0; ++step) {
    const int kind = in.ConsumeIntegralInRange<int>(0, 15);
    if (kind == 0) {
      fly_to_hold(api, backend, in);
    } else if (kind <= 5) {
      // Time passes; a pose estimate arrives (or not): mostly a camera frame period, sometimes long
      // enough for the arming gesture or a timeout; values near the setpoint or hostile.
      const std::int64_t dt_us = in.ConsumeBool()
                                     ? in.ConsumeIntegralInRange<std::int64_t>(0, kFramePeriodUs)
                                     : in.ConsumeIntegralInRange<std::int64_t>(0, kMaxStepUs);
      std::optional<PoseSample> pose;
      if (in.ConsumeIntegralInRange<int>(0, 3) != 0) {
        const CraftPose& sp = controller.status().setpoint;
        pose.emplace();
        pose->tracking = in.ConsumeIntegralInRange<int>(0, 7) != 0;
        pose->pose = {hostile_double(in, sp.x_m), hostile_double(in, sp.y_m),
                      hostile_double(in, sp.z_m), hostile_double(in, sp.yaw_deg)};
      }
      advance(backend, dt_us, pose);
    } else if (kind <= 10) {
      std::string path;
      const std::string body = operator_body(in, controller, &path);
      serve(api, backend, operator_request(path, body), path);
    } else {
      // Anything: method, route, query, Host, Origin, Content-Type and body from the input.
      HttpRequest req;
      std::string path;
      req.method(pick_method(in));
      req.target(pick_target(in, &path));
      req.version(in.ConsumeBool() ? 11 : 10);
      static const char* kHosts[] = {"127.0.0.1:8080", "localhost", "[::1]:8080",
                                     "evil.example:8080", ""};
      const std::string host =
          kHosts[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kHosts) - 1)];
      if (!host.empty()) req.set(http::field::host, host);
      if (in.ConsumeIntegralInRange<int>(0, 5) == 0) {
        req.set(http::field::origin, in.ConsumeBool() ? "http://" + host : "null");
      }
      if (in.ConsumeIntegralInRange<int>(0, 7) != 0)
        req.set(http::field::content_type, "application/json");
      req.body() = in.ConsumeIntegralInRange<int>(0, 5) == 0 ? in.ConsumeRandomLengthString(256)
                                                             : json_body(in, path);
      req.prepare_payload();
      serve(api, backend, req, path);
    }
  }
  return 0;
}
