// Registers a depth image onto the RGB camera for sources whose driver does not (OpenNI2 devices
// without hardware registration): each depth pixel is back-projected with the depth camera's
// pinhole intrinsics, moved by T_rgb_depth (maps depth-camera points into the RGB camera frame),
// projected with the RGB intrinsics, and the nearest surface wins where several land on one pixel.
// Lens distortion is ignored (Kinect v1 distortion moves pixels < 1 px over most of the image).
//
// Thread safety: register_depth() is const and may be called concurrently.
#pragma once

#include <array>
#include <optional>
#include <string>

#include "rgbdquad/capture/frame.h"

namespace rgbdquad::capture {

struct PinholeIntrinsics {
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
};

struct RegistrationOptions {
  PinholeIntrinsics depth;
  PinholeIntrinsics rgb;
  int rgb_width_px = kKinectWidthPx;
  int rgb_height_px = kKinectHeightPx;
  // T_rgb_depth: rotation (row-major 3x3) and translation in metres. Kinect v1 default: the
  // IR camera sits ~25 mm from the RGB camera along x (Khoshelham & Elberink 2012).
  std::array<double, 9> R_rgb_depth{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> t_rgb_depth_m{-0.025, 0, 0};

  bool is_valid(std::string* error) const;
};

class DepthRegistration {
 public:
  explicit DepthRegistration(const RegistrationOptions& options);
  // Returns the depth image as seen from the RGB camera (same units), or nullopt for an empty
  // or inconsistent input. Output has registered_to_rgb = true.
  std::optional<DepthFrame> register_depth(const DepthFrame& depth) const;

 private:
  RegistrationOptions options_;
};

}  // namespace rgbdquad::capture
