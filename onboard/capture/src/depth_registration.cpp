// Depth-to-RGB registration by reprojection with a z-buffer.
#include "rgbdquad/capture/depth_registration.h"

#include <cmath>
#include <limits>

namespace rgbdquad::capture {
namespace {
bool intrinsics_ok(const PinholeIntrinsics& k) {
  return std::isfinite(k.fx_px) && std::isfinite(k.fy_px) && std::isfinite(k.cx_px) &&
         std::isfinite(k.cy_px) && k.fx_px > 0 && k.fy_px > 0;
}
}  // namespace

bool RegistrationOptions::is_valid(std::string* error) const {
  if (!intrinsics_ok(depth) || !intrinsics_ok(rgb)) {
    *error = "registration intrinsics must be finite with fx, fy > 0";
    return false;
  }
  if (rgb_width_px <= 0 || rgb_height_px <= 0 || rgb_width_px > 4096 || rgb_height_px > 4096) {
    *error = "registration RGB size must be 1..4096 px";
    return false;
  }
  for (double v : R_rgb_depth) {
    if (!std::isfinite(v)) {
      *error = "R_rgb_depth must be finite";
      return false;
    }
  }
  for (double v : t_rgb_depth_m) {
    if (!std::isfinite(v)) {
      *error = "t_rgb_depth_m must be finite";
      return false;
    }
  }
  return true;
}

DepthRegistration::DepthRegistration(const RegistrationOptions& options) : options_(options) {}

std::optional<DepthFrame> DepthRegistration::register_depth(const DepthFrame& in) const {
  if (in.width <= 0 || in.height <= 0 ||
      in.depth.size() != static_cast<std::size_t>(in.width) * in.height || !(in.units_per_m > 0)) {
    return std::nullopt;
  }
  const auto& kd = options_.depth;
  const auto& kc = options_.rgb;
  const auto& R = options_.R_rgb_depth;
  const auto& t = options_.t_rgb_depth_m;
  DepthFrame out;
  out.capture_timestamp_us = in.capture_timestamp_us;
  out.width = options_.rgb_width_px;
  out.height = options_.rgb_height_px;
  out.units_per_m = in.units_per_m;
  out.registered_to_rgb = true;
  out.depth.assign(static_cast<std::size_t>(out.width) * out.height, 0);
  const double metres_per_unit = 1.0 / in.units_per_m;
  for (int v = 0; v < in.height; ++v) {
    for (int u = 0; u < in.width; ++u) {
      const std::uint16_t d = in.depth[static_cast<std::size_t>(v) * in.width + u];
      if (d == 0) continue;
      // p_depth = z * K_depth^-1 [u v 1]^T ; p_rgb = R p_depth + t
      const double z = d * metres_per_unit;
      const double x = (u - kd.cx_px) / kd.fx_px * z;
      const double y = (v - kd.cy_px) / kd.fy_px * z;
      const double xr = R[0] * x + R[1] * y + R[2] * z + t[0];
      const double yr = R[3] * x + R[4] * y + R[5] * z + t[1];
      const double zr = R[6] * x + R[7] * y + R[8] * z + t[2];
      if (!(zr > 0)) continue;
      const long ur = std::lround(kc.fx_px * xr / zr + kc.cx_px);
      const long vr = std::lround(kc.fy_px * yr / zr + kc.cy_px);
      if (ur < 0 || vr < 0 || ur >= out.width || vr >= out.height) continue;
      const double units = std::round(zr * in.units_per_m);
      if (units < 1 || units > std::numeric_limits<std::uint16_t>::max()) continue;
      auto& slot = out.depth[static_cast<std::size_t>(vr) * out.width + ur];
      const auto value = static_cast<std::uint16_t>(units);
      if (slot == 0 || value < slot) slot = value;  // nearest surface occludes farther ones
    }
  }
  return out;
}

}  // namespace rgbdquad::capture
