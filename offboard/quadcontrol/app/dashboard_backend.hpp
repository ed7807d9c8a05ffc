// What the dashboard routes (dashboard_api.hpp) need from the ground station: snapshots to show and
// the operator's three inputs. GroundStation implements it; the route fuzzer
// (tests/fuzz/fuzz_dashboard_api.cpp) backs it with a real FlightController and no threads, so the
// routes are exercised without sockets, cameras or a SLAM link.
//
// Time is a parameter: `now_us` is the ground station's monotonic clock (microseconds), read by
// the caller (DashboardApi, at the socket edge) and passed in.
//
// Thread safety: implementations are called from the HTTP server's thread(s) concurrently with
// their own threads and must lock what they share.
#pragma once

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "core/flight_controller.hpp"

namespace rgbdquad::quadcontrol {

class DashboardBackend {
 public:
  virtual ~DashboardBackend() = default;

  /// JSON snapshot for /api/state (flight state, pose, setpoint, links, map geometry).
  virtual nlohmann::json state_json(std::int64_t now_us) = 0;
  /// Newest RGB frame as JPEG / depth as greyscale PNG; nullopt before the first frame.
  virtual std::optional<std::string> rgb_jpeg() = 0;
  virtual std::optional<std::string> depth_png() = 0;
  /// The 2D floor map, PNG.
  virtual std::string map_png() = 0;
  /// At most `max_points` coloured points, JSON [x, y, z, r, g, b]...
  virtual nlohmann::json cloud_json(std::size_t max_points) = 0;
  /// The whole coloured point-cloud map, ASCII PLY.
  virtual std::string map_ply() = 0;
  /// Operator inputs: empty when accepted, else why not (then nothing changed).
  virtual std::string command(std::int64_t now_us, OperatorCommand command) = 0;
  virtual std::string waypoint(std::int64_t now_us, double x_m, double y_m) = 0;
  virtual std::string manual(std::int64_t now_us, double forward_m, double left_m, double up_m,
                             double yaw_ccw_deg) = 0;
  /// A mission's timed turn / straight move of the hold setpoint (FlightController::manoeuvre).
  /// Backends that fly no controller refuse it.
  virtual std::string manoeuvre(std::int64_t /*now_us*/, const ManoeuvreRequest& /*request*/) {
    return "manoeuvre: this backend flies no controller";
  }
};

}  // namespace rgbdquad::quadcontrol
