// Rolling-shutter correction of a frame's features. The Kinect v1's colour and infrared sensors
// are CMOS with an electronic rolling shutter: rows are exposed one after another over the
// readout time, so under rotation every row sees the scene from a slightly different attitude.
// At 100 deg/s over ~30 ms the top and bottom rows differ by ~3 deg (~27 px at fx 517): a
// global-shutter pose fit of such a frame is biased and noisy (1-5 cm per frame on fast turns),
// and a bundle of them drifts. Over one readout the camera's translation is negligible against
// its rotation (0.2 m/s x 15 ms = 3 mm), so each feature is rotated, by the predicted angular
// velocity, from its row's exposure time to the middle row's: the frame then reads as if taken
// by a global shutter at the middle row's time. The same rotation is applied to the 3D point,
// because the depth image is read out row by row by its own rolling shutter too.
//
// Thread safety: pure functions.
#pragma once

#include <Eigen/Core>

#include "slam/features/features.hpp"

namespace rgbdquad::slam {

/// Rotates each feature of `features` (its 3D point in the camera frame) from the exposure time
/// of its keypoint's row to the time of the image's middle row, for a camera turning at
/// `omega_cam_rad_per_s` (angular velocity in the camera frame) with a rolling shutter that
/// reads `rows` rows top to bottom in `readout_s`. Returns false (and changes nothing) when the
/// correction would be below 0.01 px at the image edge.
bool unroll_rotation(FrameFeatures* features, const Eigen::Vector3d& omega_cam_rad_per_s,
                     double readout_s, int rows);

}  // namespace rgbdquad::slam
