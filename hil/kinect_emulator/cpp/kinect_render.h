// kinect_render: the Kinect emulator's ray caster + depth error model in C++, a plain C API loaded
// by Python through ctypes (kinect_emulator/native.py) so the rig needs no pybind11.
//
// Contract: produces the SAME images as kinect_emulator/renderer.py (KinectEmulator.render) given
// the same pose and the same random draws. Python keeps the random number generator (numpy PCG64):
// it passes the noise slices and the dropout uniforms it would have used, so a frame stays a pure
// function of (pose, index) and the two back ends agree bit for bit (see tests/test_native.py).
// Every float operation is done in float32 in numpy's order; the target is built with
// -ffp-contract=off so no fused multiply-add changes a rounding.
//
// Frames: T_room_cam (row-major 4x4, double) maps camera points (x right, y down, z forward) to the
// room (x, y horizontal, z up, metres). Depth out: camera z in millimetres (uint16, 0 = no
// reading).
// Thread safety: a KrRenderer is immutable after kr_create; kr_render may be called from several
// threads at once with distinct output buffers.
#pragma once

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct KrRenderer KrRenderer;

// Version of this API; Python refuses a library with another one.
#define KR_API_VERSION 1
int kr_api_version(void);

// Creates a renderer. Pointers are only read during the call (the textures are copied, re-laid out
// in cache-line blocks). obstacles_lo_hi: n_obstacles x 6 doubles
// (lo x y z, hi x y z). tex_packed: tex_n x tex_h x tex_w texels, R | G << 8 | B << 16.
// Returns NULL on invalid arguments (sizes <= 0, more than 41 obstacles: face ids are uint8;
// textures over 2^32 texels).
KrRenderer* kr_create(int width, int height, double fx, double fy, double cx, double cy,
                      const double room_lo[3], const double room_hi[3], int n_obstacles,
                      const double* obstacles_lo_hi, double tile_w_m, double tile_h_m,
                      const uint32_t* tex_packed, int tex_n, int tex_h, int tex_w);
void kr_destroy(KrRenderer* r);

// Sensor model switches and draws for one frame (renderer.py's KinectOptions + noise slices).
typedef struct {
  double min_range_m;        // no reading below
  double max_range_m;        // no reading beyond
  int shadows;               // IR projector shadows
  int quantise;              // 1/8-pixel disparity quantisation
  const float* depth_noise;  // width*height standard normal draws, or NULL (no depth noise)
  const int16_t* rgb_noise;  // width*height*3 rounded RGB noise (8-bit levels), or NULL
  const float* dropout_u;    // width*height uniforms in [0, 1), or NULL (no dropouts)
  double dropout_fraction;   // a pixel drops out when its uniform < this
} KrSensor;

// Renders one frame. T_room_cam: 16 doubles, row-major. rects: n_obstacles x 4 int32 (r0, r1, c0,
// c1: the image rows/columns obstacle k can cover, from renderer.py's _screen_rect; r0 == r1 for
// none). rgb_out: width*height*3 bytes; depth_mm_out: width*height uint16.
// Returns 0, or -1 on a NULL/non-finite argument (the pose's free-space check is the caller's).
int kr_render(const KrRenderer* r, const double T_room_cam[16], const int32_t* rects,
              const KrSensor* sensor, uint8_t* rgb_out, uint16_t* depth_mm_out);

#ifdef __cplusplus
}
#endif
