// SURF orientation assignment and descriptor (Bay et al. 2008, section 4), from Haar-wavelet
// responses read off the integral image.
#pragma once

#include <opencv2/core.hpp>

#include "integral_image.hpp"

namespace rgbdquad::surf::detail {

/// Gaussian scale s of a keypoint: the 9 px filter approximates sigma = 1.2 (Bay et al. 3.3).
inline float keypoint_scale(const cv::KeyPoint& kp) { return 1.2f * kp.size / 9.f; }

/// Haar-wavelet responses (dx = right half - left half, dy = bottom half - top half, image axes)
/// of an even-sized `wavelet_px` square centred on (x, y); false if it leaves the image.
bool haar_response(const IntegralImage& integral, float x, float y, int wavelet_px, float* dx,
                   float* dy);

/// Dominant orientation in degrees [0, 360), measured from +x towards +y: responses of 4s
/// wavelets on a grid of step s inside a circle of radius 6s, weighted by a Gaussian with
/// sigma 2s, summed in a sliding pi/3 sector (every 5 deg); the direction of the longest sum.
/// Returns a negative value when no wavelet fits inside the image.
float dominant_orientation_deg(const IntegralImage& integral, const cv::KeyPoint& kp);

/// Descriptor of kp (orientation kp.angle in degrees, 0 when upright): a 20s window split in
/// 4x4 sub-regions of 5x5 samples; Haar responses of size 2s, rotated into the keypoint frame
/// and weighted by a Gaussian of sigma 3.3s; per sub-region sum dx, sum dy, sum |dx|, sum |dy|
/// (64-d) or, extended, the dx sums split by the sign of dy and the dy sums by the sign of dx
/// (128-d); normalised to unit length. out must hold 64 or 128 floats.
void compute_descriptor(const IntegralImage& integral, const cv::KeyPoint& kp, bool extended,
                        float* out);

}  // namespace rgbdquad::surf::detail
