// The flight envelope: the one place that decides whether a setpoint may be flown. Every setpoint
// the FlightController writes (take-off, manual steps, waypoints, the turn before a waypoint, the
// landing) goes through it, whatever path (dashboard API, HIL, tests) it came from:
//   - non-finite values are refused (a NaN or inf setpoint stops the PIDs acting, see pid.hpp);
//   - a waypoint further than max_distance_from_home_m from home is refused (a click is explicit:
//     moving it silently would fly somewhere the operator did not ask for);
//   - any other setpoint is clamped: horizontally onto the circle of max_distance_from_home_m
//   around
//     home, vertically into [min_height_m, max_height_m] (a manual key held at the fence stops
//     there).
// Home is the craft's x/y at take-off (ArduPilot's home is the arming position; ours needs a
// tracked pose, which take-off has). Before take-off there is no home and nothing is flown.
// Units: metres in the floor-aligned world frame (z = height above the floor). Not thread-safe:
// owned by the FlightController.
#pragma once

#include <optional>
#include <string>

namespace rgbdquad::quadcontrol {

struct EnvelopeLimits {
  double max_distance_from_home_m = 5.0;  ///< horizontal radius around home
  double min_height_m = 0.3;              ///< lowest hold setpoint (landing alone goes below)
  double max_height_m = 3.0;              ///< height ceiling of every setpoint
};

/// A setpoint position (x, y, height) in the floor frame, metres.
struct SetpointPosition {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
};

/// What a setpoint is for: the limits differ only near the floor and for the landing's fence.
enum class SetpointKind {
  kHold,     ///< hold, manual steps, waypoints: fence + [min_height_m, max_height_m]
  kTakeOff,  ///< the take-off ramp starts on the floor: fence + [0, max_height_m]
  kLanding,  ///< [0, max_height_m] where the craft is, even outside the fence (flying back first
             ///< would prolong a flight that is ending)
};

struct Contained {
  SetpointPosition position;
  bool clamped = false;  ///< true when the wanted position was outside and was moved in
};

class FlightEnvelope {
 public:
  explicit FlightEnvelope(EnvelopeLimits limits) : limits_(limits) {}

  void set_home(double x_m, double y_m);
  bool has_home() const { return home_.has_value(); }
  /// Home (x_m, y_m; z unused), nullopt before the first take-off.
  const std::optional<SetpointPosition>& home() const { return home_; }
  const EnvelopeLimits& limits() const { return limits_; }

  /// The wanted position moved into the envelope; nullopt when it is not finite (refused).
  /// Without a home only the height limits apply.
  std::optional<Contained> contain(const SetpointPosition& wanted,
                                   SetpointKind kind = SetpointKind::kHold) const;
  /// Empty when a waypoint at (x_m, y_m) may be flown, else why not.
  std::string check_waypoint(double x_m, double y_m) const;

 private:
  EnvelopeLimits limits_;
  std::optional<SetpointPosition> home_;  // z unused
};

}  // namespace rgbdquad::quadcontrol
