// SURF interest points and descriptors (H. Bay, A. Ess, T. Tuytelaars, L. Van Gool, "Speeded-Up
// Robust Features (SURF)", CVIU 110(3):346-359, 2008), implemented in the project because
// Debian's OpenCV has no xfeatures2d (see docs/surf.md for why, the normalisation that makes
// `hessian_threshold` comparable to OpenCV's SURF, the parameters and measured numbers).
//
// The detector is a real cv::Feature2D: detect(), compute(), detectAndCompute(); descriptors are
// CV_32F rows of 64 or 128 floats with unit L2 norm, matched with NORM_L2.
// KeyPoint fields as in OpenCV's SURF: pt (pixels, pixel centres at integer coordinates), size =
// side of the box filter that found it (9 px = finest scale, s = 1.2 * size / 9 is the Gaussian
// scale), angle = dominant orientation in degrees [0, 360) measured from +x towards +y (image
// axes; 0 for upright), response = Hessian determinant, octave = octave index, class_id = sign
// of the Laplacian (-1: bright blob on dark, +1: dark blob on bright).
// compute() on keypoints from elsewhere uses their pt and size, re-estimates the orientation
// (unless upright, as OpenCV's SURF does) and drops keypoints it cannot describe (non-finite,
// size <= 0, no wavelet inside the image), so the descriptor rows always match `keypoints`.
//
// Thread safety: the object holds only its immutable options, so concurrent calls on one
// instance are safe. Each call parallelises internally with cv::parallel_for_ and gives
// bit-identical results for identical input regardless of the thread count.
#pragma once

#include <opencv2/features2d.hpp>
#include <ostream>
#include <string>

namespace rgbdquad::surf {

struct SurfOptions {
  /// Number of octaves; each doubles the filter sizes and the sampling step. 4 = thesis.
  int octaves = 4;
  /// Detection scales per octave (OpenCV's nOctaveLayers); each octave evaluates
  /// scales_per_octave + 2 filter sizes (octave 1: 9, 15, 21, 27, 33 px). 3 = thesis.
  int scales_per_octave = 3;
  /// true: 128-d descriptor (sums split by the sign of the other derivative), thesis setting;
  /// false: the 64-d one.
  bool extended = true;
  /// Minimum Hessian determinant of a detection, with box responses normalised by lobe area on
  /// 8-bit intensities exactly like OpenCV's SURF, so 550 here ~ OpenCV's hessianThreshold=550
  /// (thesis value).
  double hessian_threshold = 550;
  /// true: skip orientation assignment (U-SURF), descriptors in image axes.
  bool upright = false;

  /// Checks ranges; on failure returns false and, if error is not null, says which field.
  bool is_valid(std::string* error) const;
};

std::ostream& operator<<(std::ostream& out, const SurfOptions& options);

/// Creates the SURF Feature2D. Throws std::invalid_argument (start-up boundary) if the options
/// do not validate. detect/compute throw cv::Exception (the Feature2D convention) for images that
/// are not 8-bit with 1, 3 (BGR) or 4 (BGRA) channels.
cv::Ptr<cv::Feature2D> create_surf(const SurfOptions& options);

}  // namespace rgbdquad::surf
