// ControlConfig validation and JSON loading (see control_config.hpp).
#include "core/control_config.hpp"

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "core/options_error.hpp"

namespace rgbdquad::quadcontrol {

namespace {

std::map<std::string, double*> scalar_fields(ControlConfig& c) {
  return {
      {"hold_height_m", &c.hold_height_m},
      {"hover_throttle_pct", &c.hover_throttle_pct},
      {"takeoff_climb_rate_m_per_s", &c.takeoff_climb_rate_m_per_s},
      {"takeoff_reached_tolerance_m", &c.takeoff_reached_tolerance_m},
      {"face_waypoint_tolerance_deg", &c.face_waypoint_tolerance_deg},
      {"waypoint_reached_m", &c.waypoint_reached_m},
      {"turn_skip_distance_m", &c.turn_skip_distance_m},
      {"pose_timeout_ms", &c.pose_timeout_ms},
      {"lost_hold_ms", &c.lost_hold_ms},
      {"max_pose_jump_m", &c.max_pose_jump_m},
      {"max_map_correction_m", &c.max_map_correction_m},
      {"land_descent_rate_m_per_s", &c.land_descent_rate_m_per_s},
      {"motor_stop_height_m", &c.motor_stop_height_m},
      {"land_ground_settle_ms", &c.land_ground_settle_ms},
      {"land_floor_hold_ms", &c.land_floor_hold_ms},
      {"failsafe_landing_ms", &c.failsafe_landing_ms},
      {"manual_step_m", &c.manual_step_m},
      {"manual_yaw_step_deg", &c.manual_yaw_step_deg},
      {"max_waypoint_distance_m", &c.max_waypoint_distance_m},
      {"max_distance_from_home_m", &c.max_distance_from_home_m},
      {"max_height_m", &c.max_height_m},
      {"max_manual_step_m", &c.max_manual_step_m},
      {"max_manual_yaw_step_deg", &c.max_manual_yaw_step_deg},
      {"arm_gesture_ms", &c.arm_gesture_ms},
      {"disarm_gesture_ms", &c.disarm_gesture_ms},
      {"apm_stick_deadzone_us", &c.apm_stick_deadzone_us},
      {"apm_throttle_deadband_us", &c.apm_throttle_deadband_us},
      {"max_manoeuvre_speed_m_per_s", &c.max_manoeuvre_speed_m_per_s},
      {"max_manoeuvre_yaw_rate_deg_per_s", &c.max_manoeuvre_yaw_rate_deg_per_s},
      {"max_manoeuvre_distance_m", &c.max_manoeuvre_distance_m},
      {"max_manoeuvre_turn_deg", &c.max_manoeuvre_turn_deg},
      {"manoeuvre_accel_mss", &c.manoeuvre_accel_mss},
      {"manoeuvre_yaw_accel_deg_per_s2", &c.manoeuvre_yaw_accel_deg_per_s2},
      {"apm_yaw_rate_max_deg_per_s", &c.apm_yaw_rate_max_deg_per_s},
  };
}

std::map<std::string, double*> cascade_fields(CascadeGains& g) {
  return {
      {"position_kp_per_s", &g.position_kp_per_s},
      {"velocity_kp_per_s", &g.velocity_kp_per_s},
      {"velocity_ki_per_s2", &g.velocity_ki_per_s2},
      {"integral_limit_mss", &g.integral_limit_mss},
      {"max_correction_speed_m_per_s", &g.max_correction_speed_m_per_s},
      {"angle_max_deg", &g.angle_max_deg},
  };
}

std::map<std::string, PidGains*> pid_fields(ControlConfig& c) {
  return {{"roll", &c.roll}, {"pitch", &c.pitch}, {"yaw", &c.yaw}, {"throttle", &c.throttle}};
}

}  // namespace

const char* to_string(PositionLaw law) {
  switch (law) {
    case PositionLaw::kPid:
      return "pid";
    case PositionLaw::kCascade:
      return "cascade";
  }
  return "?";
}

bool ControlConfig::is_valid(std::string* error) const {
  ControlConfig copy = *this;
  for (auto& [name, pid] : pid_fields(copy)) {
    if (std::string e; !pid->is_valid(&e)) return reject(error, "controller." + name + ": " + e);
  }
  for (auto& [name, value] : scalar_fields(copy)) {
    if (name == "apm_stick_deadzone_us" || name == "apm_throttle_deadband_us") continue;  // 0: none
    if (!std::isfinite(*value) || *value <= 0.0)
      return reject(error, "controller." + name + " must be finite and > 0");
  }
  if (!(apm_stick_deadzone_us >= 0.0 && apm_stick_deadzone_us <= 100.0)) {
    return reject(error, "controller.apm_stick_deadzone_us must be in [0, 100]");
  }
  if (!(apm_throttle_deadband_us >= 0.0 && apm_throttle_deadband_us <= 300.0)) {
    return reject(error, "controller.apm_throttle_deadband_us must be in [0, 300]");
  }
  if (!estimator.is_valid(error)) return false;
  if (!cascade.is_valid(error)) return false;
  if (position_law != PositionLaw::kPid && position_law != PositionLaw::kCascade)
    return reject(error, "controller.position_law must be \"pid\" or \"cascade\"");
  if (max_manoeuvre_yaw_rate_deg_per_s >= apm_yaw_rate_max_deg_per_s)
    return reject(
        error,
        "controller.max_manoeuvre_yaw_rate_deg_per_s must be below apm_yaw_rate_max_deg_per_s");
  if (max_manoeuvre_turn_deg > 720.0)
    return reject(error, "controller.max_manoeuvre_turn_deg must be <= 720");
  if (hover_throttle_pct >= 100.0)
    return reject(error, "controller.hover_throttle_pct must be < 100");
  if (motor_stop_height_m >= hold_height_m)
    return reject(error, "controller.motor_stop_height_m must be below hold_height_m");
  if (hold_height_m > max_height_m)
    return reject(error, "controller.hold_height_m must not exceed max_height_m");
  // Sanity bounds on the envelope itself: 120 m is the usual legal ceiling for small drones; 1 km
  // is far beyond the WiFi link's range. Larger values are typos, not envelopes.
  if (max_height_m > 120.0) return reject(error, "controller.max_height_m must be <= 120");
  if (max_distance_from_home_m > 1000.0)
    return reject(error, "controller.max_distance_from_home_m must be <= 1000");
  if (max_manual_step_m > max_distance_from_home_m)
    return reject(error, "controller.max_manual_step_m must not exceed max_distance_from_home_m");
  if (2.0 * motor_stop_height_m >= max_height_m)
    return reject(error, "controller.max_height_m must exceed 2 x motor_stop_height_m");
  if (manual_step_m > max_manual_step_m)
    return reject(error, "controller.manual_step_m must not exceed max_manual_step_m");
  if (manual_yaw_step_deg > max_manual_yaw_step_deg || max_manual_yaw_step_deg > 180.0) {
    return reject(error,
                  "controller.max_manual_yaw_step_deg must be in [manual_yaw_step_deg, 180]");
  }
  return true;
}

std::string load_control_config(const nlohmann::json& j, ControlConfig& config) {
  if (!j.is_object()) return "controller: expected an object";
  auto scalars = scalar_fields(config);
  auto pids = pid_fields(config);
  for (const auto& [key, value] : j.items()) {
    if (auto it = scalars.find(key); it != scalars.end()) {
      if (!value.is_number()) return "controller." + key + ": expected a number";
      *it->second = value.get<double>();
    } else if (key == "position_law") {
      const std::string law = value.is_string() ? value.get<std::string>() : "";
      if (law == "pid")
        config.position_law = PositionLaw::kPid;
      else if (law == "cascade")
        config.position_law = PositionLaw::kCascade;
      else
        return "controller.position_law: expected \"pid\" or \"cascade\"";
    } else if (key == "cascade") {
      if (!value.is_object()) return "controller.cascade: expected an object";
      auto fields = cascade_fields(config.cascade);
      for (const auto& [ck, cv] : value.items()) {
        const auto it = fields.find(ck);
        if (it == fields.end()) return "controller.cascade." + ck + ": unknown key";
        if (!cv.is_number()) return "controller.cascade." + ck + ": expected a number";
        *it->second = cv.get<double>();
      }
    } else if (key == "estimator") {
      if (auto e = load_estimator_options(value, config.estimator); !e.empty()) return e;
    } else if (auto pit = pids.find(key); pit != pids.end()) {
      if (!value.is_object())
        return "controller." + key + ": expected an object {kp, ki, kd, output_limit_pct}";
      for (const auto& [gk, gv] : value.items()) {
        if (!gv.is_number()) return "controller." + key + "." + gk + ": expected a number";
        PidGains& g = *pit->second;
        if (gk == "kp")
          g.kp = gv.get<double>();
        else if (gk == "ki")
          g.ki = gv.get<double>();
        else if (gk == "kd")
          g.kd = gv.get<double>();
        else if (gk == "output_limit_pct")
          g.output_limit_pct = gv.get<double>();
        else
          return "controller." + key + "." + gk + ": unknown key";
      }
    } else {
      return "controller." + key + ": unknown key";
    }
  }
  return {};
}

nlohmann::json to_json(const ControlConfig& config) {
  ControlConfig copy = config;
  nlohmann::json j = nlohmann::json::object();
  for (auto& [name, value] : scalar_fields(copy)) j[name] = *value;
  for (auto& [name, pid] : pid_fields(copy)) {
    j[name] = {{"kp", pid->kp},
               {"ki", pid->ki},
               {"kd", pid->kd},
               {"output_limit_pct", pid->output_limit_pct}};
  }
  j["position_law"] = to_string(config.position_law);
  j["cascade"] = nlohmann::json::object();
  for (auto& [name, value] : cascade_fields(copy.cascade)) j["cascade"][name] = *value;
  j["estimator"] = to_json(config.estimator);
  return j;
}

}  // namespace rgbdquad::quadcontrol
