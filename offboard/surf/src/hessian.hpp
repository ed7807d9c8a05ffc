// Fast-Hessian detector of SURF (Bay et al. 2008, section 3): box-filter approximations of the
// second Gaussian derivatives over a scale space of growing filter sizes, 3x3x3 non-maximum
// suppression and quadratic sub-pixel / sub-scale interpolation.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "integral_image.hpp"

namespace rgbdquad::surf::detail {

/// One lobe of a box filter: the half-open box [x0, x1) x [y0, y1) relative to the filter's
/// top-left corner, with `weight` = sign / lobe area (so each lobe contributes its mean intensity,
/// the normalisation OpenCV's SURF uses; see docs/surf.md).
struct HaarBox {
  int x0, y0, x1, y1;
  float weight;
};

/// The three box filters for one filter size.
struct HessianKernel {
  int size;  ///< side of the filter in pixels
  std::vector<HaarBox> dxx, dyy, dxy;
};

/// Weight of Dxy in det(H) = Dxx Dyy - (kDxyWeight Dxy)^2: corrects the box approximation to the
/// Gaussian second derivatives (Bay et al. 2008, eq. 4: |Lxy(1.2)| |Dyy(9)| / ... = 0.912 ~ 0.9).
constexpr float kDxyWeight = 0.9f;
/// Smallest filter (Bay et al.: 9x9 approximates Gaussian second derivatives with sigma 1.2).
constexpr int kBaseFilterSize = 9;
/// Filter size increment between scales of the first octave (lobe grows by 2 px each side).
constexpr int kFilterSizeStep = 6;

/// Filter size of `layer` (0-based) in `octave` (0-based): (9 + 6 layer) * 2^octave. The same
/// layout as OpenCV's SURF (each octave is the first one scaled by 2^octave, sampled every
/// 2^octave pixels), which is what makes its threshold transferable.
int filter_size(int octave, int layer);

/// Box filters of the size (9 + 6 layer) * 2^octave, lobes per Bay et al. Fig. 1 and section 3.3
/// (lobe length size/3, Dxx/Dyy lobes 2*size/3 - 1 long, Dxy lobes with a one-pixel gap), built
/// for the odd base size and scaled by 2^octave.
HessianKernel make_hessian_kernel(int octave, int layer);

/// Determinant and trace of the approximated Hessian on a grid sampled every `step` pixels.
/// Grid cell (r, c) is centred at pixel (c * step + (step - 1) / 2, r * step + (step - 1) / 2);
/// cells whose filter does not fit inside the image hold 0 and lie outside [row_min, row_max] x
/// [col_min, col_max].
struct HessianLayer {
  int filter_size = 0;
  int step = 1;
  int rows = 0, cols = 0;
  int row_min = 0, row_max = -1, col_min = 0, col_max = -1;  ///< valid cells, inclusive
  std::vector<float> det;                                    ///< rows * cols, row-major
  std::vector<float> trace;  ///< Dxx + Dyy (the Laplacian), same layout

  bool valid() const { return row_min <= row_max && col_min <= col_max; }
  float det_at(int r, int c) const { return det[static_cast<std::size_t>(r) * cols + c]; }
  float trace_at(int r, int c) const { return trace[static_cast<std::size_t>(r) * cols + c]; }
};

/// Evaluates the layer (parallel over rows). A filter larger than the image gives an empty
/// valid range.
HessianLayer compute_hessian_layer(const IntegralImage& integral, int octave, int layer);

/// Box-filter response of one kernel part at a filter top-left corner (x0, y0): sum over lobes
/// of weight * box sum. Used by compute_hessian_layer's reference path in tests.
double box_filter_response(const IntegralImage& integral, const std::vector<HaarBox>& boxes, int x0,
                           int y0);

struct DetectorParams {
  int octaves;
  int scales_per_octave;
  double hessian_threshold;
};

/// Detects interest points: maxima of det(H) above the threshold in 3x3x3 neighbourhoods
/// (position x scale) of the middle layers of each octave, refined by fitting a 3-D quadratic
/// (Brown & Lowe 2002) and dropped when the offset exceeds one sample in any dimension.
/// Output is sorted by decreasing response (ties by y, x, size): deterministic.
std::vector<cv::KeyPoint> detect_keypoints(const IntegralImage& integral,
                                           const DetectorParams& params);

}  // namespace rgbdquad::surf::detail
