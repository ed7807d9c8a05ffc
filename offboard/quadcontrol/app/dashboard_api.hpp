// HTTP routes of the web dashboard (static assets + JSON/PNG/JPEG API), mapped onto a
// DashboardBackend (the GroundStation in quad-control; dashboard_backend.hpp).
//   GET  /                   index.html (and the other files of the static dir, loaded at start-up)
//   GET  /api/state          JSON snapshot: flight state, pose, setpoint, waypoint, links, fps, map
//   GET  /api/rgb.jpg        newest RGB frame, JPEG;   GET /api/depth.png  newest depth, greyscale
//   PNG GET  /api/map.png        2D floor map (north up; geometry in /api/state "map") GET
//   /api/cloud?max=N    sub-sampled coloured point cloud (JSON [x,y,z,r,g,b]...) GET  /api/map.ply
//   the whole coloured point-cloud map, ASCII PLY POST /api/command        {"command": "arm" |
//   "disarm" | "takeoff" | "land"} POST /api/waypoint       {"x_m": .., "y_m": ..}   (floor-aligned
//   world frame) POST /api/manual         {"forward_m", "left_m", "up_m", "yaw_ccw_deg"} (setpoint
//   steps) POST /api/manoeuvre {"forward_m", "left_m", "yaw_ccw_deg", "speed_m_per_s",
//   "yaw_rate_deg_per_s"} (a timed move/turn of the hold setpoint, FlightController::manoeuvre)
// Every /api/ request passes check_api_request() first (request_guard.hpp: Host, Origin,
// Sec-Fetch-Site, a JSON Content-Type for POST, and the token when one is configured).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include "app/dashboard_backend.hpp"
#include "app/http_server.hpp"
#include "app/request_guard.hpp"

namespace rgbdquad::quadcontrol {

class DashboardApi {
 public:
  /// Loads the static assets of `static_dir` (regular files, top level only); throws
  /// std::runtime_error when the folder or its index.html is missing. `now_us` is the clock read
  /// for each request that needs the time (monotonic_now_us() in quad-control).
  DashboardApi(DashboardBackend& station, const std::string& static_dir, AccessPolicy policy,
               std::function<std::int64_t()> now_us);
  HttpResponse handle(const HttpRequest& request);

 private:
  DashboardBackend& station_;
  std::map<std::string, std::pair<std::string, std::string>>
      files_;  // path -> (content type, bytes)
  AccessPolicy policy_;
  std::function<std::int64_t()> now_us_;
};

}  // namespace rgbdquad::quadcontrol
