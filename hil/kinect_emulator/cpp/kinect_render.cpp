// kinect_render: see kinect_render.h. Each step mirrors a numpy expression of renderer.py; the
// comments name it. Two passes: (1) per pixel, ray cast (room exit planes, then obstacle slabs) and
// texture lookup; (2) per scan line, the depth model (range, projector shadows need the whole line,
// noise, quantisation, dropouts).
#include "kinect_render.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <vector>

namespace {

// Constants of renderer.py (Khoshelham & Elberink 2012; libfreenect's registration). Duplicated
// here; tests/test_native.py compares the outputs, so a drift fails there.
constexpr double kIrFocalPx = 580.0;
constexpr double kBaselineM = 0.075;
constexpr double kDisparitySubpixels = 8.0;
constexpr double kNoiseCoeffPerM = 1.425e-3;
constexpr double kTileWindowFraction = 0.6;
// A smooth surface never shadows itself by rounding (renderer.py _projector_shadow).
constexpr float kShadowTolerancePx = 0.1f;
constexpr int kMaxObstacles = 41;  // 6 + 6 * 41 face ids fit a uint8

// numpy's minimum/maximum propagate NaN (std::min/max do not).
// One compare per select: GCC 12 vectorises these, not a select on (a < b) | isnan(a).
inline float np_min(float a, float b) {
  float r = (a < b) ? a : b;
  r = (b != b) ? b : r;
  return (a != a) ? a : r;
}
inline float np_max(float a, float b) {
  float r = (a > b) ? a : b;
  r = (b != b) ? b : r;
  return (a != a) ? a : r;
}

// np.round / rint (round half to even) without a libm call: adding and removing 1.5 * 2^23 leaves
// the nearest integer in the default rounding mode for |x| < 2^22; larger values, inf and NaN are
// already what rint returns. Bit-identical to rintf (tests/test_native.py).
inline float rint_even(float x) {
  constexpr float kMagic = 12582912.0f;  // 1.5 * 2^23
  // Without -ffast-math the compiler may not fold (x + m) - m to x.
  const float rounded = (x + kMagic) - kMagic;
  return std::fabs(x) < 4194304.0f ? rounded : x;
}

// floorf for |x| < 2^31 (tile numbers) without a libm call (x86-64 baseline has no roundss).
// Differs from floorf only in the sign of a zero, which no caller can see (it goes through an int).
inline float floor_small(float x) {
  const float f = static_cast<float>(static_cast<int32_t>(x));
  return f > x ? f - 1.0f : f;
}

// Textures are stored in 4x4-texel blocks (64 bytes, one cache line): a minified tile reads every
// other texel of every other row, so blocks cut the cache lines touched per frame about 4x.
constexpr int kBlock = 4;

struct Box {
  double lo[3];
  double hi[3];
};

// Per pixel of a row: the hit point's in-plane coordinates on its face, divided into tile numbers
// (ti, tj) and the fraction within the tile (fu, fv) - renderer.py _shade up to the tile hash.
// A function of its own so that __restrict tells the vectoriser the rows do not overlap.
void tile_coords_row(int W, const float* __restrict zr, const uint8_t* __restrict fr,
                     const float* __restrict rxr, const float* __restrict ryr,
                     const float (&Rf)[3][3], const float (&of)[3], float tile_w, float tile_h,
                     float* __restrict fu_out, float* __restrict fv_out, int32_t* __restrict ti_out,
                     int32_t* __restrict tj_out) {
  const float R00 = Rf[0][0], R01 = Rf[0][1], R02 = Rf[0][2];
  const float R10 = Rf[1][0], R11 = Rf[1][1], R12 = Rf[1][2];
  const float R20 = Rf[2][0], R21 = Rf[2][1], R22 = Rf[2][2];
  const float o0 = of[0], o1 = of[1], o2 = of[2];
  for (int col = 0; col < W; ++col) {
    const float t = zr[col];
    const float rx = rxr[col];
    const float ry = ryr[col];
    float d0 = rx * R00;
    d0 += ry * R01;
    d0 += R02;
    float d1 = rx * R10;
    d1 += ry * R11;
    d1 += R12;
    float d2 = rx * R20;
    d2 += ry * R21;
    d2 += R22;
    float p0 = d0 * t;
    p0 += o0;
    float p1 = d1 * t;
    p1 += o1;
    float p2 = d2 * t;
    p2 += o2;
    // (face % 6) / 2 in float arithmetic (exact for face < 256; SSE2 has no 32-bit vector divide):
    // side = face % 6; axis 0 for side 0..1, 1 for 2..3, 2 for 4..5.
    const float face_f = static_cast<float>(fr[col]);
    const float side = face_f - 6.0f * floor_small(face_f * (1.0f / 6.0f) + 1e-3f);
    float fu = (side < 2.0f ? p1 : p0) / tile_w;
    float fv = (side >= 4.0f ? p1 : p2) / tile_h;
    const float ti = floor_small(fu);
    const float tj = floor_small(fv);
    fu -= ti;
    fv -= tj;
    fu_out[col] = fu;
    fv_out[col] = fv;
    ti_out[col] = static_cast<int32_t>(ti);
    tj_out[col] = static_cast<int32_t>(tj);
  }
}

}  // namespace

struct KrRenderer {
  int width = 0;
  int height = 0;
  double fx = 0;
  std::vector<float> ray_x;  // camera-frame direction (ray_x, ray_y, 1) per pixel
  std::vector<float> ray_y;
  double room_lo[3] = {};
  double room_hi[3] = {};
  std::vector<Box> obstacles;
  float tile_w_m = 0;
  float tile_h_m = 0;
  std::unique_ptr<uint32_t[]> tex_blocks;  // (n, rows / 4, cols / 4, 4, 4), padded to whole blocks
  int blocks_x = 0;
  int blocks_y = 0;
  int tex_n = 0;
  int tex_h = 0;
  int tex_w = 0;
  int win_w = 0;
  int win_h = 0;
};

namespace {
inline uint32_t texel_offset(const KrRenderer& r, int32_t i, int32_t y, int32_t x) {
  const uint32_t block =
      (static_cast<uint32_t>(i) * r.blocks_y + y / kBlock) * r.blocks_x + x / kBlock;
  return block * (kBlock * kBlock) + (y % kBlock) * kBlock + x % kBlock;
}
}  // namespace

extern "C" int kr_api_version(void) { return KR_API_VERSION; }

extern "C" KrRenderer* kr_create(int width, int height, double fx, double fy, double cx, double cy,
                                 const double room_lo[3], const double room_hi[3], int n_obstacles,
                                 const double* obstacles_lo_hi, double tile_w_m, double tile_h_m,
                                 const uint32_t* tex_packed, int tex_n, int tex_h, int tex_w) {
  if (width <= 0 || height <= 0 || !(fx > 0) || !(fy > 0) || !room_lo || !room_hi ||
      n_obstacles < 0 || n_obstacles > kMaxObstacles || (n_obstacles > 0 && !obstacles_lo_hi) ||
      !(tile_w_m > 0) || !(tile_h_m > 0) || !tex_packed || tex_n <= 0 || tex_h <= 1 || tex_w <= 1) {
    return nullptr;
  }
  auto r = std::unique_ptr<KrRenderer>(new (std::nothrow) KrRenderer);
  if (!r) return nullptr;
  r->width = width;
  r->height = height;
  r->fx = fx;
  const size_t n = static_cast<size_t>(width) * height;
  r->ray_x.resize(n);
  r->ray_y.resize(n);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      // ((u - cx) / fx).astype(float32): computed in double, then rounded once.
      r->ray_x[static_cast<size_t>(v) * width + u] = static_cast<float>((u - cx) / fx);
      r->ray_y[static_cast<size_t>(v) * width + u] = static_cast<float>((v - cy) / fy);
    }
  }
  for (int a = 0; a < 3; ++a) {
    r->room_lo[a] = room_lo[a];
    r->room_hi[a] = room_hi[a];
  }
  for (int k = 0; k < n_obstacles; ++k) {
    Box b;
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = obstacles_lo_hi[6 * k + a];
      b.hi[a] = obstacles_lo_hi[6 * k + 3 + a];
    }
    r->obstacles.push_back(b);
  }
  r->tile_w_m = static_cast<float>(tile_w_m);
  r->tile_h_m = static_cast<float>(tile_h_m);
  r->blocks_x = (tex_w + kBlock - 1) / kBlock;
  r->blocks_y = (tex_h + kBlock - 1) / kBlock;
  const size_t n_blocked = static_cast<size_t>(tex_n) * r->blocks_y * r->blocks_x * kBlock * kBlock;
  if (n_blocked > UINT32_MAX) return nullptr;  // texel offsets are uint32
  r->tex_blocks.reset(new (std::nothrow) uint32_t[n_blocked]());
  if (!r->tex_blocks) return nullptr;
  for (int i = 0; i < tex_n; ++i) {
    for (int y = 0; y < tex_h; ++y) {
      for (int x = 0; x < tex_w; ++x) {
        r->tex_blocks[texel_offset(*r, i, y, x)] =
            tex_packed[(static_cast<size_t>(i) * tex_h + y) * tex_w + x];
      }
    }
  }
  r->tex_n = tex_n;
  r->tex_h = tex_h;
  r->tex_w = tex_w;
  // int(self._tex_w * TILE_WINDOW_FRACTION): Python float product, truncated.
  r->win_w = static_cast<int>(tex_w * kTileWindowFraction);
  r->win_h = static_cast<int>(tex_h * kTileWindowFraction);
  if (r->win_w >= tex_w || r->win_h >= tex_h) return nullptr;
  return r.release();
}

extern "C" void kr_destroy(KrRenderer* r) { delete r; }

extern "C" int kr_render(const KrRenderer* r, const double T_room_cam[16], const int32_t* rects,
                         const KrSensor* sensor, uint8_t* rgb_out, uint16_t* depth_mm_out) {
  if (!r || !T_room_cam || !sensor || !rgb_out || !depth_mm_out ||
      (!r->obstacles.empty() && !rects)) {
    return -1;
  }
  for (int i = 0; i < 16; ++i) {
    if (!std::isfinite(T_room_cam[i])) return -1;
  }
  const int W = r->width;
  const int H = r->height;
  const size_t n_px = static_cast<size_t>(W) * H;
  const int n_obst = static_cast<int>(r->obstacles.size());
  float Rf[3][3];  // f32(R[a, c])
  double o[3];
  float of[3];
  float lo_o[3];  // f32(lo[a] - o[a]) (difference in double)
  float hi_o[3];
  for (int a = 0; a < 3; ++a) {
    for (int c = 0; c < 3; ++c) Rf[a][c] = static_cast<float>(T_room_cam[4 * a + c]);
    o[a] = T_room_cam[4 * a + 3];
    of[a] = static_cast<float>(o[a]);
    lo_o[a] = static_cast<float>(r->room_lo[a] - o[a]);
    hi_o[a] = static_cast<float>(r->room_hi[a] - o[a]);
  }
  std::vector<float> box_lo_o(static_cast<size_t>(n_obst) * 3);
  std::vector<float> box_hi_o(static_cast<size_t>(n_obst) * 3);
  for (int k = 0; k < n_obst; ++k) {
    for (int a = 0; a < 3; ++a) {
      box_lo_o[3 * k + a] = static_cast<float>(r->obstacles[k].lo[a] - o[a]);
      box_hi_o[3 * k + a] = static_cast<float>(r->obstacles[k].hi[a] - o[a]);
    }
  }
  const float inf = std::numeric_limits<float>::infinity();
  const uint32_t tex_n = static_cast<uint32_t>(r->tex_n);
  const uint32_t span_x = static_cast<uint32_t>(r->tex_w - r->win_w);
  const uint32_t span_y = static_cast<uint32_t>(r->tex_h - r->win_h);
  const float win_w1 = static_cast<float>(r->win_w - 1);
  const float win_h1 = static_cast<float>(r->win_h - 1);
  // Per-thread scratch, kept between frames (fresh 2 MB buffers cost page faults every frame).
  thread_local std::vector<float> z;
  thread_local std::vector<uint8_t> faces;
  thread_local std::vector<uint32_t> texel_index;
  z.resize(n_px);
  faces.resize(n_px);
  texel_index.resize(n_px);
  float* const zs = z.data();  // plain pointers: a thread_local access is a call per use
  uint8_t* const face_at = faces.data();
  uint32_t* const texel_at = texel_index.data();
  const uint32_t* const tex = r->tex_blocks.get();
  const float* const ray_x = r->ray_x.data();
  const float* const ray_y = r->ray_y.data();
  // Camera ray (ray_x, ray_y, 1) in the room: da = cx * R[a,0]; da += cy * R[a,1]; da += R[a,2].

  // ---- pass 1a: room exit (renderer.py raycast). Branch-free, so the compiler vectorises it.
  const float R00 = Rf[0][0], R01 = Rf[0][1], R02 = Rf[0][2];
  const float R10 = Rf[1][0], R11 = Rf[1][1], R12 = Rf[1][2];
  const float R20 = Rf[2][0], R21 = Rf[2][1], R22 = Rf[2][2];
  for (size_t p = 0; p < n_px; ++p) {
    const float rx = ray_x[p];
    const float ry = ray_y[p];
    float d0 = rx * R00;  // written out per axis: an inner loop here stops the vectoriser
    d0 += ry * R01;
    d0 += R02;
    float d1 = rx * R10;
    d1 += ry * R11;
    d1 += R12;
    float d2 = rx * R20;
    d2 += ry * R21;
    d2 += R22;
    const float i0 = 1.0f / d0;
    const float i1 = 1.0f / d1;
    const float i2 = 1.0f / d2;
    const float ts0 = np_max(i0 * hi_o[0], i0 * lo_o[0]);
    const float ts1 = np_max(i1 * hi_o[1], i1 * lo_o[1]);
    const float ts2 = np_max(i2 * hi_o[2], i2 * lo_o[2]);
    // Nearest exit plane; ties go to the lower axis (strict <).
    const bool sel1 = ts1 < ts0;
    float t = np_min(ts0, ts1);
    const bool sel2 = ts2 < t;
    t = np_min(t, ts2);
    int32_t face = sel1 ? (d1 > 0) + 2 : (d0 > 0);
    face = sel2 ? (d2 > 0) + 4 : face;
    zs[p] = t;
    face_at[p] = static_cast<uint8_t>(face);
  }
  // ---- pass 1b: obstacles, each over its screen rectangle (slab test), in order.
  thread_local std::vector<float> row_t_buf;
  thread_local std::vector<int32_t> row_face_buf;
  row_t_buf.resize(W);
  row_face_buf.resize(W);
  float* const row_t = row_t_buf.data();
  int32_t* const row_face = row_face_buf.data();
  for (int k = 0; k < n_obst; ++k) {
    const int32_t* rc = rects + 4 * k;
    const int r0 = rc[0] < 0 ? 0 : rc[0];
    const int r1 = rc[1] > H ? H : rc[1];
    const int c0 = rc[2] < 0 ? 0 : rc[2];
    const int c1 = rc[3] > W ? W : rc[3];
    const float bl0 = box_lo_o[3 * k], bl1 = box_lo_o[3 * k + 1], bl2 = box_lo_o[3 * k + 2];
    const float bh0 = box_hi_o[3 * k], bh1 = box_hi_o[3 * k + 1], bh2 = box_hi_o[3 * k + 2];
    const int32_t face_base = 6 + 6 * k;
    for (int row = r0; row < r1; ++row) {
      // Results go to row buffers written unconditionally, then are copied back: a select that
      // may keep zs[p] is otherwise turned into a conditional store, which stops vectorisation.
      for (int col = c0; col < c1; ++col) {
        // Axes written out (as in pass 1a) so that the loop vectorises.
        const size_t p = static_cast<size_t>(row) * W + col;
        const float rx = ray_x[p];
        const float ry = ray_y[p];
        float d0 = rx * R00;
        d0 += ry * R01;
        d0 += R02;
        float d1 = rx * R10;
        d1 += ry * R11;
        d1 += R12;
        float d2 = rx * R20;
        d2 += ry * R21;
        d2 += R22;
        const float i0 = 1.0f / d0;
        const float i1 = 1.0f / d1;
        const float i2 = 1.0f / d2;
        // Slab test; entering through the min side when moving +, the max side when moving -.
        // tmin starts at -inf, so axis 0 always sets it (numpy: near > -inf, or NaN stays -inf).
        const float a0 = i0 * bl0, b0 = i0 * bh0;
        const float near0 = np_min(a0, b0);
        const bool later0 = near0 > -inf;
        int32_t entry = later0 ? static_cast<int32_t>(d0 < 0) : 0;
        float tmin = later0 ? near0 : -inf;
        float tmax = np_min(inf, np_max(a0, b0));
        const float a1 = i1 * bl1, b1 = i1 * bh1;
        const float near1 = np_min(a1, b1);
        const bool later1 = near1 > tmin;
        entry = later1 ? static_cast<int32_t>(d1 < 0) + 2 : entry;
        tmin = later1 ? near1 : tmin;
        tmax = np_min(tmax, np_max(a1, b1));
        const float a2 = i2 * bl2, b2 = i2 * bh2;
        const float near2 = np_min(a2, b2);
        const bool later2 = near2 > tmin;
        entry = later2 ? static_cast<int32_t>(d2 < 0) + 4 : entry;
        tmin = later2 ? near2 : tmin;
        tmax = np_min(tmax, np_max(a2, b2));
        const float t_room = zs[p];
        // hit = tmax >= tmin and tmin > 0 and tmin < t_room, as one select per compare (a select
        // on the conjunction is not vectorised).
        const int32_t face_room = face_at[p];
        float t_new = (tmax >= tmin) ? tmin : t_room;
        int32_t face_new = (tmax >= tmin) ? entry + face_base : face_room;
        t_new = (tmin > 0) ? t_new : t_room;
        face_new = (tmin > 0) ? face_new : face_room;
        t_new = (tmin < t_room) ? t_new : t_room;
        face_new = (tmin < t_room) ? face_new : face_room;
        row_t[col] = t_new;
        row_face[col] = face_new;
      }
      const size_t base = static_cast<size_t>(row) * W;
      for (int col = c0; col < c1; ++col) {
        zs[base + col] = row_t[col];
        face_at[base + col] = static_cast<uint8_t>(row_face[col]);
      }
    }
  }
  // ---- pass 1c: texture coordinates (renderer.py _shade).
  // The tile hash's three modulos cost more than the ray cast; neighbouring pixels are mostly on
  // the same tile, so the last (face, tile) is remembered.
  uint32_t last_face = 0xffffffffu;
  int32_t last_ti = 0;
  int32_t last_tj = 0;
  uint32_t tile_hash = 0;
  int32_t idx = 0;
  int32_t off_x = 0;
  int32_t off_y = 0;
  thread_local std::vector<float> row_fu_buf;
  thread_local std::vector<float> row_fv_buf;
  thread_local std::vector<int32_t> row_ti_buf;
  thread_local std::vector<int32_t> row_tj_buf;
  row_fu_buf.resize(W);
  row_fv_buf.resize(W);
  row_ti_buf.resize(W);
  row_tj_buf.resize(W);
  float* const row_fu = row_fu_buf.data();
  float* const row_fv = row_fv_buf.data();
  int32_t* const row_ti = row_ti_buf.data();
  int32_t* const row_tj = row_tj_buf.data();
  const float tile_w = r->tile_w_m;
  const float tile_h = r->tile_h_m;
  for (int row = 0; row < H; ++row) {
    const size_t row_begin = static_cast<size_t>(row) * W;
    const size_t row_end = row_begin + W;
    // In-plane coordinates and tile numbers: branch-free, vectorised.
    tile_coords_row(W, zs + row_begin, face_at + row_begin, ray_x + row_begin, ray_y + row_begin,
                    Rf, of, tile_w, tile_h, row_fu, row_fv, row_ti, row_tj);
    for (int col = 0; col < W; ++col) {
      const size_t p = row_begin + col;
      const uint32_t face = face_at[p];
      const int32_t ti_i = row_ti[col];
      const int32_t tj_i = row_tj[col];
      float fu = row_fu[col];
      float fv = row_fv[col];
      if (face != last_face || ti_i != last_ti || tj_i != last_tj) {
        uint32_t h = face * 73856093u;
        h ^= static_cast<uint32_t>(ti_i) * 19349663u;
        h ^= static_cast<uint32_t>(tj_i) * 83492791u;
        idx = static_cast<int32_t>(h % tex_n);
        off_x = static_cast<int32_t>((h >> 7) % span_x);
        off_y = static_cast<int32_t>((h >> 17) % span_y);
        tile_hash = h;
        last_face = face;
        last_ti = ti_i;
        last_tj = tj_i;
      }
      if ((tile_hash >> 27) & 1u) fu = 1.0f - fu;
      fu *= win_w1;
      const int32_t tcol = static_cast<int32_t>(fu) + off_x;
      fv = 1.0f - fv;  // rows go down
      fv *= win_h1;
      const int32_t trow = static_cast<int32_t>(fv) + off_y;
      const uint32_t at = texel_offset(*r, idx, trow, tcol);
      texel_at[p] = at;
      __builtin_prefetch(tex + at);
    }
    // ---- pass 1d: the gather of the row, in a loop of its own after its prefetches: each miss
    // inside the per-pixel dependency chain above stalled it (3x slower).
    for (size_t p = row_begin; p < row_end; ++p) {
      const uint32_t texel = tex[texel_at[p]];
      uint8_t* out = rgb_out + 3 * p;
      for (int c = 0; c < 3; ++c) {
        int v = static_cast<int>((texel >> (8 * c)) & 0xffu);
        if (sensor->rgb_noise) {
          v += sensor->rgb_noise[3 * p + c];
          v = v < 0 ? 0 : (v > 255 ? 255 : v);
        }
        out[c] = static_cast<uint8_t>(v);
      }
    }
  }

  // ---- pass 2: depth model per scan line (renderer.py _sensor_depth, _projector_shadow)
  const float min_r = static_cast<float>(sensor->min_range_m);
  const float max_r = static_cast<float>(sensor->max_range_m);
  const float proj_fb = static_cast<float>(r->fx * kBaselineM);
  const float noise_coeff = static_cast<float>(kNoiseCoeffPerM);
  const float k_disp = static_cast<float>(kIrFocalPx * kBaselineM * kDisparitySubpixels);
  const float drop_frac = static_cast<float>(sensor->dropout_fraction);
  std::vector<float> up(W);
  std::vector<uint8_t> missing(W);
  for (int row = 0; row < H; ++row) {
    float* zr = zs + static_cast<size_t>(row) * W;
    for (int c = 0; c < W; ++c) {
      missing[c] = !(zr[c] >= min_r) || zr[c] > max_r;
    }
    if (sensor->shadows) {
      // Projector BASELINE_M to the right: pixel u lands on projector column u - f b / z. Scanning
      // from the right, shadowed when a pixel to its right already lands at or left of it.
      for (int c = 0; c < W; ++c) up[c] = static_cast<float>(c) - proj_fb / zr[c];
      float run_min = up[W - 1];
      for (int c = W - 2; c >= 0; --c) {
        if (up[c] > run_min + kShadowTolerancePx) missing[c] = 1;
        run_min = np_min(run_min, up[c]);
      }
    }
    const size_t base = static_cast<size_t>(row) * W;
    const float* noise = sensor->depth_noise ? sensor->depth_noise + base : nullptr;
    const float* drop = sensor->dropout_u ? sensor->dropout_u + base : nullptr;
    uint16_t* out = depth_mm_out + base;
    const bool quantise = sensor->quantise != 0;
    for (int c = 0; c < W; ++c) {
      float zc = zr[c];
      if (noise) {
        float nz = noise[c] * noise_coeff;  // sigma_z = coeff z^2
        nz *= zc;
        nz *= zc;
        zc += nz;
      }
      if (quantise) {
        const float disparity = rint_even(k_disp / zc);  // 1/8-pixel steps, half to even
        zc = k_disp / disparity;
      }
      const bool dropped = drop ? drop[c] < drop_frac : false;
      const float mm = rint_even(zc * 1000.0f);
      // Missing readings are 0; a valid reading is within 0.5..4.5 m, so the casts are in range.
      const float kept = (missing[c] | dropped) ? 0.0f : mm;
      out[c] = static_cast<uint16_t>(static_cast<int32_t>(kept));
    }
  }
  return 0;
}
