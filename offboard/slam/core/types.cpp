// Intrinsics validation and the named TUM cameras.
#include "slam/core/types.hpp"

#include <cmath>

namespace slam {

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
  Intrinsics k;
  if (name == "fr1") {
    // defaults above
  } else if (name == "fr2") {
    k.fx_px = 520.9; k.fy_px = 521.0; k.cx_px = 325.1; k.cy_px = 249.7;
    k.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
  } else if (name == "fr3") {
    k.fx_px = 535.4; k.fy_px = 539.2; k.cx_px = 320.1; k.cy_px = 247.6;
    k.distortion = {0, 0, 0, 0, 0};
  } else {
    if (error) *error = "unknown camera '" + name + "' (expected fr1, fr2 or fr3)";
    return false;
  }
  *out = k;
  return true;
}

}  // namespace slam
