// Fast-Hessian detector (see hessian.hpp).
#include "hessian.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/core/utility.hpp>

namespace rgbdquad::surf::detail {
namespace {

// A lobe as flat offsets into the integral table relative to the filter's top-left corner.
struct BoxOffsets {
  std::ptrdiff_t top_left, top_right, bottom_left, bottom_right;
  float weight;
};

std::vector<BoxOffsets> to_offsets(const std::vector<HaarBox>& boxes, std::ptrdiff_t stride) {
  std::vector<BoxOffsets> out;
  for (const auto& b : boxes) {
    out.push_back({b.y0 * stride + b.x0, b.y0 * stride + b.x1, b.y1 * stride + b.x0,
                   b.y1 * stride + b.x1, b.weight});
  }
  return out;
}

// Dxx and Dyy have three equal-area lobes weighted w, -2w, w: the same as the whole span at w
// plus the middle lobe at -3w, i.e. 2 boxes (8 look-ups) instead of 3 (12).
std::vector<HaarBox> fuse_three_lobes(const std::vector<HaarBox>& lobes) {
  if (lobes.size() != 3 || lobes[0].weight != lobes[2].weight) return lobes;
  HaarBox whole{std::min(lobes[0].x0, lobes[2].x0), std::min(lobes[0].y0, lobes[2].y0),
                std::max(lobes[0].x1, lobes[2].x1), std::max(lobes[0].y1, lobes[2].y1),
                lobes[0].weight};
  HaarBox middle = lobes[1];
  middle.weight -= lobes[0].weight;
  return {whole, middle};
}

inline double box(const double* corner, const BoxOffsets& b) {
  return b.weight * (corner[b.bottom_right] - corner[b.bottom_left] - corner[b.top_right] +
                     corner[b.top_left]);
}

// Fixed box counts (2 + 2 + 4) so the per-cell loop is fully unrolled.
template <std::size_t N>
std::array<BoxOffsets, N> fixed(const std::vector<BoxOffsets>& boxes) {
  CV_Assert(boxes.size() == N);
  std::array<BoxOffsets, N> out;
  std::copy(boxes.begin(), boxes.end(), out.begin());
  return out;
}

HaarBox make_box(int x0, int y0, int x1, int y1, float sign, int scale) {
  const float area = static_cast<float>((x1 - x0) * (y1 - y0) * scale * scale);
  return {x0 * scale, y0 * scale, x1 * scale, y1 * scale, sign / area};
}

// Solves the 3x3 system A x = b by Cramer's rule (A symmetric); false if singular.
bool solve3(const float A[3][3], const float b[3], float x[3]) {
  const double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
                     A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
                     A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
  if (std::abs(det) < 1e-12) return false;
  for (int k = 0; k < 3; ++k) {
    double M[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) M[i][j] = (j == k) ? b[i] : A[i][j];
    const double dk = M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
                      M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
                      M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
    x[k] = static_cast<float>(dk / det);
  }
  return true;
}

}  // namespace

int filter_size(int octave, int layer) {
  return (kBaseFilterSize + kFilterSizeStep * layer) << octave;
}

HessianKernel make_hessian_kernel(int octave, int layer) {
  const int n = kBaseFilterSize + kFilterSizeStep * layer;  // odd base size
  const int lobe = n / 3;
  const int centre = (n - 1) / 2;
  const int scale = 1 << octave;
  HessianKernel k;
  k.size = n * scale;
  // Dxx: three lobes side by side along x (+1, -2, +1), 2*lobe - 1 tall, centred in y.
  const int y0 = centre - (lobe - 1), y1 = centre + lobe;
  k.dxx = {make_box(0, y0, lobe, y1, 1.f, scale), make_box(lobe, y0, 2 * lobe, y1, -2.f, scale),
           make_box(2 * lobe, y0, 3 * lobe, y1, 1.f, scale)};
  // Dyy: the transpose.
  k.dyy = {make_box(y0, 0, y1, lobe, 1.f, scale), make_box(y0, lobe, y1, 2 * lobe, -2.f, scale),
           make_box(y0, 2 * lobe, y1, 3 * lobe, 1.f, scale)};
  // Dxy: four lobe x lobe squares around the centre with a one-pixel gap; +1 on the diagonal.
  const int a0 = centre - lobe, a1 = centre, b0 = centre + 1, b1 = centre + 1 + lobe;
  k.dxy = {make_box(a0, a0, a1, a1, 1.f, scale), make_box(b0, a0, b1, a1, -1.f, scale),
           make_box(a0, b0, a1, b1, -1.f, scale), make_box(b0, b0, b1, b1, 1.f, scale)};
  return k;
}

double box_filter_response(const IntegralImage& integral, const std::vector<HaarBox>& boxes, int x0,
                           int y0) {
  double sum = 0.0;
  for (const auto& b : boxes) {
    sum += b.weight * integral.box_sum(x0 + b.x0, y0 + b.y0, b.x1 - b.x0, b.y1 - b.y0);
  }
  return sum;
}

HessianLayer compute_hessian_layer(const IntegralImage& integral, int octave, int layer) {
  const HessianKernel kernel = make_hessian_kernel(octave, layer);
  HessianLayer out;
  out.filter_size = kernel.size;
  out.step = 1 << octave;
  out.rows = integral.height() / out.step;
  out.cols = integral.width() / out.step;
  out.det.assign(static_cast<std::size_t>(out.rows) * out.cols, 0.f);
  out.trace.assign(out.det.size(), 0.f);
  // Filter top-left for cell r is r*step - half; it must satisfy 0 <= top-left and
  // top-left + size <= image side.
  const int half = (kernel.size - out.step) / 2;
  const int step = out.step;
  auto first_valid = [&](void) { return (half + step - 1) / step; };
  auto last_valid = [&](int side) {
    const int span = side - kernel.size + half;
    return span < 0 ? -1 : span / step;
  };
  out.row_min = first_valid();
  out.col_min = first_valid();
  out.row_max = std::min(last_valid(integral.height()), out.rows - 1);
  out.col_max = std::min(last_valid(integral.width()), out.cols - 1);
  if (!out.valid()) return out;

  const auto dxx = fixed<2>(to_offsets(fuse_three_lobes(kernel.dxx), integral.stride()));
  const auto dyy = fixed<2>(to_offsets(fuse_three_lobes(kernel.dyy), integral.stride()));
  const auto dxy = fixed<4>(to_offsets(kernel.dxy, integral.stride()));
  const float dxy_weight_sq = kDxyWeight * kDxyWeight;
  cv::parallel_for_(cv::Range(out.row_min, out.row_max + 1), [&](const cv::Range& rows) {
    for (int r = rows.start; r < rows.end; ++r) {
      const double* corner = integral.row(r * step - half) + (out.col_min * step - half);
      float* det_row = &out.det[static_cast<std::size_t>(r) * out.cols];
      float* trace_row = &out.trace[static_cast<std::size_t>(r) * out.cols];
      for (int c = out.col_min; c <= out.col_max; ++c, corner += step) {
        const float lxx = static_cast<float>(box(corner, dxx[0]) + box(corner, dxx[1]));
        const float lyy = static_cast<float>(box(corner, dyy[0]) + box(corner, dyy[1]));
        const float lxy = static_cast<float>(box(corner, dxy[0]) + box(corner, dxy[1]) +
                                             box(corner, dxy[2]) + box(corner, dxy[3]));
        det_row[c] = lxx * lyy - dxy_weight_sq * lxy * lxy;
        trace_row[c] = lxx + lyy;
      }
    }
  });
  return out;
}

std::vector<cv::KeyPoint> detect_keypoints(const IntegralImage& integral,
                                           const DetectorParams& params) {
  std::vector<cv::KeyPoint> keypoints;
  const int layers_per_octave = params.scales_per_octave + 2;
  const float threshold = static_cast<float>(params.hessian_threshold);
  for (int octave = 0; octave < params.octaves; ++octave) {
    std::vector<HessianLayer> layers;
    for (int l = 0; l < layers_per_octave; ++l) {
      layers.push_back(compute_hessian_layer(integral, octave, l));
      if (!layers.back().valid()) break;  // larger filters do not fit either
    }
    for (int l = 1; l + 1 < static_cast<int>(layers.size()); ++l) {
      const HessianLayer& below = layers[l - 1];
      const HessianLayer& mid = layers[l];
      const HessianLayer& above = layers[l + 1];
      // The largest filter has the smallest valid region; one more cell for the 3x3 window.
      const int r0 = above.row_min + 1, r1 = above.row_max - 1;
      const int c0 = above.col_min + 1, c1 = above.col_max - 1;
      if (r0 > r1 || c0 > c1) continue;
      std::vector<std::vector<cv::KeyPoint>> per_row(static_cast<std::size_t>(r1 - r0 + 1));
      cv::parallel_for_(cv::Range(r0, r1 + 1), [&](const cv::Range& range) {
        for (int r = range.start; r < range.end; ++r) {
          auto& found = per_row[static_cast<std::size_t>(r - r0)];
          for (int c = c0; c <= c1; ++c) {
            const float v = mid.det_at(r, c);
            if (!(v > threshold)) continue;
            // N[s][k]: 3x3 neighbourhood (k = 3*(dy+1) + (dx+1)) in layer l-1+s.
            float N[3][9];
            bool is_max = true;
            const HessianLayer* stack[3] = {&below, &mid, &above};
            for (int s = 0; s < 3 && is_max; ++s) {
              for (int dy = -1; dy <= 1; ++dy) {
                for (int dx = -1; dx <= 1; ++dx) {
                  const float n = stack[s]->det_at(r + dy, c + dx);
                  N[s][3 * (dy + 1) + (dx + 1)] = n;
                  if ((s != 1 || dy != 0 || dx != 0) && !(v > n)) is_max = false;
                }
              }
            }
            if (!is_max) continue;
            // Quadratic fit: offset x = -H^-1 g in (x, y, scale) sample units.
            const float g[3] = {-(N[1][5] - N[1][3]) / 2, -(N[1][7] - N[1][1]) / 2,
                                -(N[2][4] - N[0][4]) / 2};
            const float dxy = (N[1][8] - N[1][6] - N[1][2] + N[1][0]) / 4;
            const float dxs = (N[2][5] - N[2][3] - N[0][5] + N[0][3]) / 4;
            const float dys = (N[2][7] - N[2][1] - N[0][7] + N[0][1]) / 4;
            const float H[3][3] = {{N[1][3] - 2 * N[1][4] + N[1][5], dxy, dxs},
                                   {dxy, N[1][1] - 2 * N[1][4] + N[1][7], dys},
                                   {dxs, dys, N[0][4] - 2 * N[1][4] + N[2][4]}};
            float off[3];
            if (!solve3(H, g, off)) continue;
            // An extremum more than one sample away belongs to a neighbour (Lowe 2004).
            if (std::abs(off[0]) > 1.f || std::abs(off[1]) > 1.f || std::abs(off[2]) > 1.f)
              continue;
            const float centre_offset = 0.5f * static_cast<float>(mid.step - 1);
            cv::KeyPoint kp;
            kp.pt.x = static_cast<float>(c * mid.step) + centre_offset + off[0] * mid.step;
            kp.pt.y = static_cast<float>(r * mid.step) + centre_offset + off[1] * mid.step;
            kp.size = static_cast<float>(mid.filter_size) +
                      off[2] * static_cast<float>(mid.filter_size - below.filter_size);
            kp.angle = -1.f;
            kp.response = v;
            kp.octave = octave;
            const float trace = mid.trace_at(r, c);
            kp.class_id = (trace > 0) - (trace < 0);
            found.push_back(kp);
          }
        }
      });
      for (auto& row : per_row) keypoints.insert(keypoints.end(), row.begin(), row.end());
    }
  }
  std::stable_sort(keypoints.begin(), keypoints.end(),
                   [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
                     if (a.response != b.response) return a.response > b.response;
                     if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
                     if (a.pt.x != b.pt.x) return a.pt.x < b.pt.x;
                     return a.size < b.size;
                   });
  return keypoints;
}

}  // namespace rgbdquad::surf::detail
