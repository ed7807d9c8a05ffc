// Depth re-timed to the colour image. The Kinect captures colour and depth with separate clocks:
// in the TUM fr1 recordings the depth image paired with a colour image is 3-11 ms older. While
// the camera turns at 90 deg/s, 8 ms moves the image ~6.5 px (fx 517), so a keypoint found in the
// colour image reads the depth of a neighbouring surface point: at depth edges a wrong depth, on
// slanted surfaces a biased one, and both pull the pose. Over so short an interval the camera's
// translation is negligible (0.2 m/s x 8 ms = 1.6 mm) against its rotation, so the depth image is
// warped by the rotation alone: the pure-rotation homography K R K^-1, with each depth value
// re-expressed along the rotated optical axis.
//
// Thread safety: pure functions.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slam/core/types.hpp"

namespace rgbdquad::slam {

/// The depth image (CV_16UC1, raw units, 0 = no reading) as it would have been captured
/// `colour_minus_depth_s` later, by a camera rotating at `omega_cam_rad_per_s` (angular velocity
/// in the camera frame). Nearest-neighbour: depth is never interpolated across surfaces. Returns
/// `depth` itself when the rotation over the interval is below 0.01 px at the image edge.
cv::Mat align_depth_to_colour_time(const cv::Mat& depth, const Intrinsics& intrinsics,
                                   const Eigen::Vector3d& omega_cam_rad_per_s,
                                   double colour_minus_depth_s);

}  // namespace rgbdquad::slam
