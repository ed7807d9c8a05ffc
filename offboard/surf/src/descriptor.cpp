// SURF orientation and descriptor (see descriptor.hpp).
#include "descriptor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace rgbdquad::surf::detail {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kDegPerRad = 180.f / kPi;
/// Orientation: samples within 6s of the keypoint (Bay et al. 4.1).
constexpr int kOrientationRadiusSamples = 6;
/// Upper bound of the samples inside that circle (the bounding square), for stack buffers;
/// must stay <= 256 for the uint8 sort indices.
constexpr std::size_t kMaxOrientationSamples =
    (2 * kOrientationRadiusSamples + 1) * (2 * kOrientationRadiusSamples + 1);
static_assert(kMaxOrientationSamples <= 256, "orientation sort indices are uint8");
/// Orientation: Gaussian sigma 2s (Bay et al. 4.1), in sample units.
constexpr float kOrientationSigmaSamples = 2.f;
/// Orientation: the sliding sector spans pi/3 (Bay et al. 4.1) ...
constexpr float kOrientationWindowDeg = 60.f;
/// ... and is moved in 5 deg steps (as OpenCV; the result is the continuous direction of the
/// best sector's sum, so the step only limits which sectors are tried).
constexpr int kOrientationSearchStepDeg = 5;
/// Descriptor: 4x4 sub-regions of 5x5 samples spaced s = a 20s window (Bay et al. 4.2).
constexpr int kSubRegions = 4;
constexpr int kSamplesPerSubRegion = 5;
constexpr int kWindowSamples = kSubRegions * kSamplesPerSubRegion;
/// Descriptor: Gaussian sigma 3.3s centred on the keypoint (Bay et al. 4.2).
constexpr float kDescriptorSigmaSamples = 3.3f;

struct OrientationSample {
  int i, j;
  float weight;
};

const std::vector<OrientationSample>& orientation_samples() {
  static const std::vector<OrientationSample> samples = [] {
    std::vector<OrientationSample> s;
    const float two_sigma_sq = 2.f * kOrientationSigmaSamples * kOrientationSigmaSamples;
    for (int i = -kOrientationRadiusSamples; i <= kOrientationRadiusSamples; ++i) {
      for (int j = -kOrientationRadiusSamples; j <= kOrientationRadiusSamples; ++j) {
        if (i * i + j * j <= kOrientationRadiusSamples * kOrientationRadiusSamples) {
          s.push_back({i, j, std::exp(-static_cast<float>(i * i + j * j) / two_sigma_sq)});
        }
      }
    }
    return s;
  }();
  return samples;
}

/// Gaussian weights of the 20 x 20 descriptor samples (sigma 3.3s, in sample units), row-major.
const std::array<float, kWindowSamples * kWindowSamples>& descriptor_weights() {
  static const auto weights = [] {
    std::array<float, kWindowSamples * kWindowSamples> w{};
    const float two_sigma_sq = 2.f * kDescriptorSigmaSamples * kDescriptorSigmaSamples;
    for (int gy = 0; gy < kWindowSamples; ++gy) {
      for (int gx = 0; gx < kWindowSamples; ++gx) {
        const float v = static_cast<float>(gy) + 0.5f - 0.5f * kWindowSamples;
        const float u = static_cast<float>(gx) + 0.5f - 0.5f * kWindowSamples;
        w[static_cast<std::size_t>(gy * kWindowSamples + gx)] =
            std::exp(-(u * u + v * v) / two_sigma_sq);
      }
    }
    return w;
  }();
  return weights;
}

int even_wavelet_px(float length_px) {
  return std::max(2, 2 * static_cast<int>(std::lround(length_px / 2.f)));
}

}  // namespace

bool haar_response(const IntegralImage& integral, float x, float y, int wavelet_px, float* dx,
                   float* dy) {
  // Pixel i covers [i - 0.5, i + 0.5), so the wavelet's left edge x - w/2 is table column
  // x - w/2 + 0.5. The corners are generally fractional: the summed-area table is interpolated
  // bilinearly (all 9 corners share one fractional offset), so the response moves smoothly with
  // the sample position instead of snapping to whole pixels - this matters on the rotated
  // descriptor grid, whose spacing s is only 1.2 px at the finest scale.
  const float left = x - 0.5f * static_cast<float>(wavelet_px) + 0.5f;
  const float top = y - 0.5f * static_cast<float>(wavelet_px) + 0.5f;
  const float fl = std::floor(left), ft = std::floor(top);
  const int ix = static_cast<int>(fl), iy = static_cast<int>(ft);
  if (ix < 0 || iy < 0 || ix + wavelet_px + 1 > integral.width() ||
      iy + wavelet_px + 1 > integral.height()) {
    return false;
  }
  const double fx = left - fl, fy = top - ft;
  const double w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
  const int h = wavelet_px / 2;
  const int offs[3] = {0, h, wavelet_px};
  double c[3][3];  // c[row][col]: interpolated table at the corner (offs[col], offs[row])
  for (int i = 0; i < 3; ++i) {
    const double* r0 = integral.row(iy + offs[i]) + ix;
    const double* r1 = integral.row(iy + offs[i] + 1) + ix;
    for (int j = 0; j < 3; ++j) {
      const int o = offs[j];
      c[i][j] = w00 * r0[o] + w10 * r0[o + 1] + w01 * r1[o] + w11 * r1[o + 1];
    }
  }
  const double left_half = c[2][1] - c[2][0] - c[0][1] + c[0][0];
  const double right_half = c[2][2] - c[2][1] - c[0][2] + c[0][1];
  const double upper_half = c[1][2] - c[1][0] - c[0][2] + c[0][0];
  const double lower_half = c[2][2] - c[2][0] - c[1][2] + c[1][0];
  *dx = static_cast<float>(right_half - left_half);
  *dy = static_cast<float>(lower_half - upper_half);
  return true;
}

float dominant_orientation_deg(const IntegralImage& integral, const cv::KeyPoint& kp) {
  const float s = keypoint_scale(kp);
  const int wavelet = even_wavelet_px(4.f * s);
  // Fixed-size buffers on the stack: no heap traffic per keypoint.
  std::array<float, kMaxOrientationSamples> rx, ry, angle_deg;
  std::size_t n = 0;
  for (const auto& smp : orientation_samples()) {
    float dx = 0.f, dy = 0.f;
    if (!haar_response(integral, kp.pt.x + static_cast<float>(smp.j) * s,
                       kp.pt.y + static_cast<float>(smp.i) * s, wavelet, &dx, &dy)) {
      continue;
    }
    rx[n] = dx * smp.weight;
    ry[n] = dy * smp.weight;
    float a = std::atan2(ry[n], rx[n]) * kDegPerRad;
    if (a < 0.f) a += 360.f;
    angle_deg[n] = a;
    ++n;
  }
  if (n == 0) return -1.f;
  // Sector sums via prefix sums over the responses sorted by angle, unrolled over
  // [-360, 720) so sectors that wrap around 0 deg are contiguous: each of the 72 sectors costs
  // two binary searches instead of a pass over all samples. A sample is in the sector centred
  // on c when |angle - c| < 30 deg (modulo 360).
  std::array<std::uint8_t, kMaxOrientationSamples> order;
  for (std::size_t k = 0; k < n; ++k) order[k] = static_cast<std::uint8_t>(k);
  std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n),
            [&](std::uint8_t a, std::uint8_t b) {
              return angle_deg[a] < angle_deg[b] || (angle_deg[a] == angle_deg[b] && a < b);
            });
  std::array<float, 3 * kMaxOrientationSamples> unrolled_deg;
  std::array<double, 3 * kMaxOrientationSamples + 1> prefix_x, prefix_y;
  prefix_x[0] = prefix_y[0] = 0.0;
  for (std::size_t copy = 0; copy < 3; ++copy) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t idx = copy * n + k;
      unrolled_deg[idx] = angle_deg[order[k]] + 360.f * (static_cast<float>(copy) - 1.f);
      prefix_x[idx + 1] = prefix_x[idx] + rx[order[k]];
      prefix_y[idx + 1] = prefix_y[idx] + ry[order[k]];
    }
  }
  const auto first = unrolled_deg.begin();
  const auto last = unrolled_deg.begin() + static_cast<std::ptrdiff_t>(3 * n);
  double best_x = 0.0, best_y = 0.0, best_norm_sq = -1.0;
  for (int centre = 0; centre < 360; centre += kOrientationSearchStepDeg) {
    const float lo_deg = static_cast<float>(centre) - 0.5f * kOrientationWindowDeg;
    const float hi_deg = static_cast<float>(centre) + 0.5f * kOrientationWindowDeg;
    const auto lo = static_cast<std::size_t>(std::upper_bound(first, last, lo_deg) - first);
    const auto hi = static_cast<std::size_t>(std::lower_bound(first, last, hi_deg) - first);
    const double sx = prefix_x[hi] - prefix_x[lo];
    const double sy = prefix_y[hi] - prefix_y[lo];
    const double norm_sq = sx * sx + sy * sy;
    if (norm_sq > best_norm_sq) {
      best_norm_sq = norm_sq;
      best_x = sx;
      best_y = sy;
    }
  }
  float angle = static_cast<float>(std::atan2(best_y, best_x)) * kDegPerRad;
  if (angle < 0.f) angle += 360.f;
  if (angle >= 360.f) angle -= 360.f;
  return angle;
}

void compute_descriptor(const IntegralImage& integral, const cv::KeyPoint& kp, bool extended,
                        float* out) {
  const int dims = extended ? 128 : 64;
  std::fill(out, out + dims, 0.f);
  const float s = keypoint_scale(kp);
  const int wavelet = even_wavelet_px(2.f * s);
  const float angle_rad = kp.angle >= 0.f ? kp.angle / kDegPerRad : 0.f;
  const float co = std::cos(angle_rad), si = std::sin(angle_rad);
  const auto& weights = descriptor_weights();
  const int per_region = extended ? 8 : 4;
  for (int gy = 0; gy < kWindowSamples; ++gy) {
    // Sample centres at (k + 0.5 - 10) s along the keypoint's axes u (its orientation) and v.
    const float v = static_cast<float>(gy) + 0.5f - 0.5f * kWindowSamples;
    for (int gx = 0; gx < kWindowSamples; ++gx) {
      const float u = static_cast<float>(gx) + 0.5f - 0.5f * kWindowSamples;
      const float x = kp.pt.x + s * (u * co - v * si);
      const float y = kp.pt.y + s * (u * si + v * co);
      float dx = 0.f, dy = 0.f;
      if (!haar_response(integral, x, y, wavelet, &dx, &dy)) continue;  // outside: no gradient
      const float w = weights[static_cast<std::size_t>(gy * kWindowSamples + gx)];
      // Responses in the keypoint frame: project onto u = (co, si) and v = (-si, co).
      const float du = w * (dx * co + dy * si);
      const float dv = w * (-dx * si + dy * co);
      float* bin = out + per_region * ((gy / kSamplesPerSubRegion) * kSubRegions +
                                       gx / kSamplesPerSubRegion);
      if (!extended) {
        bin[0] += du;
        bin[1] += dv;
        bin[2] += std::abs(du);
        bin[3] += std::abs(dv);
      } else {
        if (dv >= 0.f) {
          bin[0] += du;
          bin[1] += std::abs(du);
        } else {
          bin[2] += du;
          bin[3] += std::abs(du);
        }
        if (du >= 0.f) {
          bin[4] += dv;
          bin[5] += std::abs(dv);
        } else {
          bin[6] += dv;
          bin[7] += std::abs(dv);
        }
      }
    }
  }
  double norm_sq = 0.0;
  for (int k = 0; k < dims; ++k) norm_sq += static_cast<double>(out[k]) * out[k];
  if (norm_sq <= 0.0) return;  // flat patch: all zeros (matches nothing well)
  const float inv = static_cast<float>(1.0 / std::sqrt(norm_sq));
  for (int k = 0; k < dims; ++k) out[k] *= inv;
}

}  // namespace rgbdquad::surf::detail
