// Intrinsics validation and the named TUM cameras.
#include "slam/core/types.hpp"

#include <chrono>
#include <cmath>
#include <ctime>

namespace rgbdquad::slam {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::int64_t thread_cpu_now_ns() {
  timespec ts{};
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0) return 0;
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

const char* to_string(TrackingState s) {
  switch (s) {
    case TrackingState::kInitialising:
      return "initialising";
    case TrackingState::kTracking:
      return "tracking";
    case TrackingState::kLost:
      return "lost";
  }
  return "?";
}

bool Intrinsics::is_valid(std::string* error) const {
  const bool finite = std::isfinite(fx_px) && std::isfinite(fy_px) && std::isfinite(cx_px) &&
                      std::isfinite(cy_px) && std::isfinite(depth_units_per_m);
  if (!finite || fx_px <= 0 || fy_px <= 0 || depth_units_per_m <= 0) {
    if (error) *error = "intrinsics: fx, fy and depth_units_per_m must be finite and > 0";
    return false;
  }
  for (double d : distortion) {
    if (!std::isfinite(d)) {
      if (error) *error = "intrinsics: distortion coefficients must be finite";
      return false;
    }
  }
  return true;
}

bool Intrinsics::from_name(const std::string& name, Intrinsics* out, std::string* error) {
  const rgbdquad::camera::TumCamera* cam = rgbdquad::camera::find_tum_camera(name);
  if (cam == nullptr) {
    if (error) *error = "unknown camera '" + name + "' (expected fr1, fr2, fr3 or ros_default)";
    return false;
  }
  Intrinsics k;
  k.fx_px = cam->fx_px;
  k.fy_px = cam->fy_px;
  k.cx_px = cam->cx_px;
  k.cy_px = cam->cy_px;
  k.distortion = cam->distortion;
  k.depth_units_per_m = cam->depth_units_per_m;
  *out = k;
  return true;
}

}  // namespace rgbdquad::slam
