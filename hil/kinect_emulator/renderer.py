"""Kinect v1 renderer: RGB + registered depth (mm) from a camera pose in a textured box room.

Geometry is exact ray casting, vectorised over all 640x480 pixels: inside an axis-aligned room each
ray leaves through exactly one of the two planes of each axis, so the hit is min over three
divisions;
obstacle boxes use the slab test. Depth is the camera-z distance (what a Kinect reports), registered
to RGB (one camera for both, as FREENECT_DEPTH_REGISTERED / TUM depth are).

Depth error model (Khoshelham & Elberink 2012, "Accuracy and resolution of Kinect depth data"):
  * random error sigma_z = 1.425e-3 * z^2 (m), z in metres;
  * quantisation in disparity: the Kinect reports 1/8-pixel disparity steps, with f = 580 px and
    baseline b = 7.5 cm, so the depth step is z^2 / (8 f b) (about 1.5 mm at 0.7 m, 12 mm at 2 m);
  * range: no reading below 0.5 m or beyond 4.5 m (the v1's usable range);
  * projector shadows: a point the IR projector (b to the side) cannot see has no reading (holes
  beside
    every occluding edge), computed per scan line from the projector's disparity ordering;
  * random dropouts (specular / low-return pixels) at `dropout_fraction`.
Blank-frame injection returns an all-zero frame (what a USB hiccup delivers) for the chosen indices.

Time: the caller passes the capture time; the frame carries capture and availability time
(capture + latency_ms). Randomness: one numpy Generator per emulator, seeded by the options; the
Gaussian depth and RGB noise are read at a random offset from banks of NOISE_BANK_FRAMES frames of
draws (independent per pixel within a frame; a frame's field is a shifted copy of the bank).
`render_indexed` makes a frame a pure function of (pose, index). Not thread-safe.

Back ends (options.renderer): the C++ library (cpp/kinect_render.cpp via native.py, built by
`make build`) does the per-pixel work with the random draws made here, and gives the same images
bit for bit (tests/test_native.py); this file's numpy code is the reference and the fallback.
Speed (640x480, one core, `bench.py`): numpy ~14 ms per frame on an idle core of this machine (ray
cast ~4 ms, texture ~6 ms, depth model ~3 ms); the figures of both back ends are in docs/hil.md.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field

import numpy as np
from rgbd_protocol.tum_cameras import TUM_FR1

from kinect_emulator.room import Room

# Kinect v1 geometry for the noise model (Khoshelham & Elberink 2012; libfreenect's registration):
IR_FOCAL_PX = 580.0  # IR camera focal length in pixels
BASELINE_M = 0.075  # IR camera - IR projector baseline
DISPARITY_SUBPIXELS = 8  # the v1 reports disparity in 1/8 pixel
NOISE_COEFF_PER_M = 1.425e-3  # sigma_z = NOISE_COEFF_PER_M * z^2
# Obstacle culling: a box with a corner closer than this in front of the camera (or behind it) is
# tested over the whole image; otherwise over its projected rectangle grown by this margin (float32
# ray directions vs float64 corner projection differ by far less than a pixel).
SCREEN_RECT_MIN_Z_M = 1e-3
SCREEN_RECT_MARGIN_PX = 2
# Noise banks: NOISE_BANK_FRAMES frames of Gaussian draws made once per emulator from the stream
# (seed, NOISE_BANK_STREAM, kind) - a value no frame index takes - and read at a random offset per
# frame: per-pixel draws for 0.9 M RGB and 0.3 M depth values cost more than the ray cast.
NOISE_BANK_STREAM = 2**40
NOISE_BANK_FRAMES = 4
# Each texture tile shows a 60 % window of its photograph (see _shade).
TILE_WINDOW_FRACTION = 0.6
# Kinect v1 exposure -> frame complete on the host (USB), ms. NO PUBLISHED MEASUREMENT of this
# delay for the v1 was found: the figures in print are end-to-end game/skeleton latencies (e.g. the
# 150 ms Rare quoted for Kinect Sports, Digital Foundry 2010), which include tracking and display.
# The value is a LOWER BOUND derived from how a frame travels: libfreenect receives the 11-bit
# 640x480 depth frame (422 400 bytes) in isochronous packets of 1760 bytes with a 12-byte header
# (cameras.c: DEPTH_PKTSIZE), i.e. 242 packets; at one packet per 125 us USB 2.0 microframe the
# frame streams for 30.2 ms, so its last byte reaches the host ~30 ms after readout begins. The
# PS1080's own depth computation and the exposure itself would add to it. Used by the latency
# budget (exposure -> PWM = this + capture -> PWM) and, when KinectOptions.latency_ms is set to it,
# by LiveKinect, which then holds each frame until exposure + latency_ms.
KINECT_V1_EXPOSURE_TO_USB_MS = 30.0

# Back ends: "cpp" = libkinect_render.so (native.py; built by `make build`), "numpy" = this file,
# "auto" = cpp when built, else numpy (logged). Default from RGBD_KINECT_RENDERER, else "auto".
RENDERERS = ("auto", "cpp", "numpy")
RENDERER_ENV = "RGBD_KINECT_RENDERER"

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics (pixels). Default: TUM Freiburg 1 colour camera (the real frames'
    camera; protocol/camera/tum_cameras.json)."""

    width: int = 640
    height: int = 480
    fx: float = TUM_FR1.fx_px
    fy: float = TUM_FR1.fy_px
    cx: float = TUM_FR1.cx_px
    cy: float = TUM_FR1.cy_px


@dataclass(frozen=True)
class KinectOptions:
    intrinsics: Intrinsics = field(default_factory=Intrinsics)
    fps: float = 30.0  # Kinect v1 streams at 30 Hz
    # capture -> available to the capture source; LiveKinect holds each frame until exposure + this
    # (0: as soon as rendered). The Kinect v1's own delay: KINECT_V1_EXPOSURE_TO_USB_MS.
    latency_ms: float = 0.0
    min_range_m: float = 0.5  # v1 near limit
    max_range_m: float = 4.5  # v1 usable far limit
    depth_noise: bool = True
    quantise: bool = True
    shadows: bool = True
    dropout_fraction: float = 0.005  # ~0.5 % isolated holes on matte indoor surfaces
    rgb_noise_std: float = 2.0  # 8-bit levels of sensor noise
    blank_frames: frozenset[int] = frozenset()  # frame indices delivered all-zero
    seed: int = 1
    # Which back end renders (RENDERERS); both give the same images (tests/test_native.py).
    renderer: str = field(default_factory=lambda: os.environ.get(RENDERER_ENV, "auto"))

    def validate(self) -> None:
        i = self.intrinsics
        if i.width <= 0 or i.height <= 0 or not (i.fx > 0 and i.fy > 0):
            raise ValueError("KinectOptions.intrinsics: width/height/fx/fy must be > 0")
        if not (math.isfinite(self.fps) and 0 < self.fps <= 120):
            raise ValueError(f"KinectOptions.fps must be in (0, 120], got {self.fps}")
        if not (math.isfinite(self.latency_ms) and self.latency_ms >= 0):
            raise ValueError(f"KinectOptions.latency_ms must be >= 0, got {self.latency_ms}")
        if not 0 < self.min_range_m < self.max_range_m:
            raise ValueError("KinectOptions: need 0 < min_range_m < max_range_m")
        if not 0 <= self.dropout_fraction < 1:
            raise ValueError("KinectOptions.dropout_fraction must be in [0, 1)")
        if not self.rgb_noise_std >= 0:
            raise ValueError("KinectOptions.rgb_noise_std must be >= 0")
        if self.renderer not in RENDERERS:
            raise ValueError(
                f"KinectOptions.renderer must be one of {RENDERERS}, got {self.renderer!r}"
            )

    @property
    def frame_period_us(self) -> int:
        return int(round(1e6 / self.fps))


@dataclass(frozen=True)
class KinectFrame:
    index: int
    capture_us: int  # exposure time (simulated)
    available_us: int  # when the capture source can read it (capture + latency)
    rgb: np.ndarray  # (H, W, 3) uint8
    depth_mm: np.ndarray  # (H, W) uint16, 0 = no reading
    T_room_cam: np.ndarray  # ground truth pose (4x4)
    blank: bool


class KinectEmulator:
    def __init__(self, room: Room, options: KinectOptions | None = None) -> None:
        self.options = options or KinectOptions()
        self.options.validate()
        self.room = room
        self._rng = np.random.default_rng(self.options.seed)
        i = self.options.intrinsics
        u, v = np.meshgrid(
            np.arange(i.width, dtype=np.float64), np.arange(i.height, dtype=np.float64)
        )
        # Ray directions in the camera frame with z = 1, so the ray parameter t is the depth itself.
        self._ray_x = ((u - i.cx) / i.fx).astype(np.float32).ravel()
        self._ray_y = ((v - i.cy) / i.fy).astype(np.float32).ravel()
        self._index = 0
        self._rgb_noise_bank: np.ndarray | None = None  # built on first use
        self._depth_noise_bank: np.ndarray | None = None
        tex = room.textures
        flat = tex.reshape(-1, 3).astype(np.uint32)
        self._tex_packed = flat[:, 0] | (flat[:, 1] << 8) | (flat[:, 2] << 16)
        # Before the byte swap: the library takes values, not bytes.
        self._native = self._make_native(self._tex_packed)
        if not np.little_endian:
            self._tex_packed = self._tex_packed.byteswap()  # the bytes must read R, G, B, 0
        self._tex_n, self._tex_h, self._tex_w = tex.shape[0], tex.shape[1], tex.shape[2]
        n_faces = 6 + 6 * len(room.obstacles)
        if n_faces > 256:
            raise ValueError("at most 41 obstacles (face ids are uint8)")
        faces = np.arange(256, dtype=np.uint32)
        self._face_axis = ((faces % 6) // 2).astype(np.uint8)  # face id -> axis of its normal
        self._face_hash = faces * np.uint32(73856093)  # face id -> its term of the tile hash

    def _make_native(self, tex_packed: np.ndarray):
        """The C++ back end per options.renderer, or None (numpy). "cpp" raises OSError when the
        library is missing; "auto" falls back to numpy with a warning. The choice is logged and kept
        in self.renderer ("cpp" | "numpy")."""
        want = self.options.renderer
        native = None
        if want != "numpy":
            from kinect_emulator.native import NativeRenderer, library_path

            tex = self.room.textures
            try:
                native = NativeRenderer(
                    self.room, self.options.intrinsics, tex_packed, tex.shape[:3]
                )
            except OSError as e:
                if want == "cpp":
                    raise
                log.warning("Kinect emulator: C++ renderer not available (%s); using numpy", e)
            else:
                log.info("Kinect emulator: C++ renderer (%s)", library_path())
        if native is None:
            log.info("Kinect emulator: numpy renderer")
        self.renderer = "cpp" if native is not None else "numpy"
        return native

    # ---- geometry
    # -----------------------------------------------------------------------------------
    def raycast(self, T_room_cam: np.ndarray) -> tuple[np.ndarray, tuple, np.ndarray]:
        """Exact depth (m, camera z) per pixel, the hit point (x, y, z arrays) and the face id per
        pixel.

        Face id: axis*2 + (1 on the max side) for the room's faces 0..5; 6 + 6*k + the same for
        obstacle k (uint8). Per-axis float32 arrays (not (N, 3)) keep every operation a contiguous
        vector op. Inside the room the ray leaves through the far plane of each axis, at
        max((lo - o) / d, (hi - o) / d) (one is negative; d = +-0 gives +inf). An obstacle is only
        tested over the image rectangle its corners project to (a box in front of the camera
        projects inside the hull of its corners), or over the whole image when a corner is behind.
        """
        T, R, o = self._checked_pose(T_room_cam)
        f32 = np.float32
        cx, cy = self._ray_x, self._ray_y  # camera-frame direction (cx, cy, 1)
        d = []
        for a in range(3):
            da = cx * f32(R[a, 0])
            da += cy * f32(R[a, 1])
            da += f32(R[a, 2])
            d.append(da)
        lo, hi = self.room.bounds.lo_m, self.room.bounds.hi_m
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = [np.divide(f32(1.0), d[a], dtype=f32) for a in range(3)]
            ts = []
            for a in range(3):
                ta = inv[a] * f32(hi[a] - o[a])
                np.maximum(ta, inv[a] * f32(lo[a] - o[a]), out=ta)
                ts.append(ta)
            # Nearest exit plane; ties go to the lower axis (strict <).
            sel1 = ts[1] < ts[0]
            t = np.minimum(ts[0], ts[1])
            sel2 = ts[2] < t
            np.minimum(t, ts[2], out=t)
            pos = [(d[a] > 0).view(np.uint8) for a in range(3)]
            face = np.where(sel1, pos[1] + np.uint8(2), pos[0])
            np.copyto(face, pos[2] + np.uint8(4), where=sel2)
            H, W = self.options.intrinsics.height, self.options.intrinsics.width
            for k, box in enumerate(self.room.obstacles):
                rect = self._screen_rect(box, R, o)
                if rect is None:
                    continue
                r0, r1, c0, c1 = rect
                sub = lambda arr, r0=r0, r1=r1, c0=c0, c1=c1: arr.reshape(H, W)[r0:r1, c0:c1]  # noqa: E731
                t_s = sub(t)
                tmin = np.full(t_s.shape, -np.inf, f32)
                tmax = np.full(t_s.shape, np.inf, f32)
                entry = np.zeros(t_s.shape, np.uint8)
                for a in range(3):
                    ia = sub(inv[a])
                    t1 = ia * f32(box.lo_m[a] - o[a])
                    t2 = ia * f32(box.hi_m[a] - o[a])
                    near = np.minimum(t1, t2)
                    far = np.maximum(t1, t2)
                    # Entering through the min side when moving +, the max side when moving -.
                    later = near > tmin
                    np.copyto(entry, (sub(d[a]) < 0).view(np.uint8) + np.uint8(2 * a), where=later)
                    np.copyto(tmin, near, where=later)
                    np.minimum(tmax, far, out=tmax)
                hit = (tmax >= tmin) & (tmin > 0) & (tmin < t_s)
                np.copyto(t_s, tmin, where=hit)
                np.copyto(sub(face), entry + np.uint8(6 + 6 * k), where=hit)
        pts = []
        for a in range(3):
            p = d[a] * t
            p += f32(o[a])
            pts.append(p)
        return t, tuple(pts), face

    def _checked_pose(self, T_room_cam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(T, R, o) of a finite 4x4 pose whose origin is in the room's free space; ValueError
        otherwise."""
        T = np.asarray(T_room_cam, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError("T_room_cam must be a finite 4x4 matrix")
        R, o = T[:3, :3], T[:3, 3]
        if not self.room.contains(o):
            raise ValueError(f"camera position {o.tolist()} is outside the room's free space")
        return T, R, o

    def _screen_rect(self, box, R: np.ndarray, o: np.ndarray) -> tuple[int, int, int, int] | None:
        """Rows r0:r1, columns c0:c1 the box can cover; the whole image if a corner is behind the
        camera; None if it covers no pixel."""
        i = self.options.intrinsics
        corners = np.array(
            [
                [x, y, z]
                for x in (box.lo_m[0], box.hi_m[0])
                for y in (box.lo_m[1], box.hi_m[1])
                for z in (box.lo_m[2], box.hi_m[2])
            ]  # fmt: skip
        )
        pc = (corners - o) @ R  # rows: R^T (p - o), camera frame
        if np.any(pc[:, 2] <= SCREEN_RECT_MIN_Z_M):
            return 0, i.height, 0, i.width
        u = i.fx * pc[:, 0] / pc[:, 2] + i.cx
        v = i.fy * pc[:, 1] / pc[:, 2] + i.cy
        c0 = max(0, int(np.floor(u.min())) - SCREEN_RECT_MARGIN_PX)
        c1 = min(i.width, int(np.ceil(u.max())) + SCREEN_RECT_MARGIN_PX + 1)
        r0 = max(0, int(np.floor(v.min())) - SCREEN_RECT_MARGIN_PX)
        r1 = min(i.height, int(np.ceil(v.max())) + SCREEN_RECT_MARGIN_PX + 1)
        return (r0, r1, c0, c1) if r0 < r1 and c0 < c1 else None

    def _shade(self, pts: tuple, face: np.ndarray) -> np.ndarray:
        """Texture lookup (nearest neighbour) for every hit point; (N, 3) uint8."""
        f32, u32 = np.float32, np.uint32
        x, y, z = pts
        axis = self._face_axis[face]
        # In-plane coordinates (u horizontal-ish, v vertical-ish) for each face orientation.
        u = np.where(axis == 0, y, x)
        v = np.where(axis == 2, y, z)
        fu = u
        fu /= f32(self.room.tile_w_m)
        fv = v
        fv /= f32(self.room.tile_h_m)
        ti = np.floor(fu)
        tj = np.floor(fv)
        fu -= ti
        fv -= tj
        # Hash of (face, tile) -> which photograph, which 60 % window of it and whether mirrored:
        # neighbours differ, the same place always looks the same, and the few dozen shipped frames
        # (many nearly alike) give far more distinct texture than whole-image tiling. uint32
        # arithmetic (wrapping) is half the cost of int64 over 307 200 pixels.
        h = self._face_hash[face]
        h ^= ti.astype(np.int32).view(u32) * u32(19349663)
        h ^= tj.astype(np.int32).view(u32) * u32(83492791)
        win_w = int(self._tex_w * TILE_WINDOW_FRACTION)
        win_h = int(self._tex_h * TILE_WINDOW_FRACTION)
        idx = (h % u32(self._tex_n)).view(np.int32)
        off_x = ((h >> u32(7)) % u32(self._tex_w - win_w)).view(np.int32)
        off_y = ((h >> u32(17)) % u32(self._tex_h - win_h)).view(np.int32)
        mirrored = ((h >> u32(27)) & u32(1)).view(np.int32).astype(bool)
        np.subtract(f32(1.0), fu, out=fu, where=mirrored)
        fu *= f32(win_w - 1)
        col = fu.astype(np.int32)
        col += off_x
        fv = np.subtract(f32(1.0), fv, out=fv)  # rows go down
        fv *= f32(win_h - 1)
        row = fv.astype(np.int32)
        row += off_y
        idx *= np.int32(self._tex_h)
        idx += row
        idx *= np.int32(self._tex_w)
        idx += col
        # One uint32 (R | G << 8 | B << 16) per texel: a 4-byte gather, then the RGB bytes.
        return self._tex_packed.take(idx).view(np.uint8).reshape(-1, 4)[:, :3]

    # ---- sensor
    # -------------------------------------------------------------------------------------
    def render(self, T_room_cam: np.ndarray, capture_us: int) -> KinectFrame:
        """Next frame seen from T_room_cam at simulated time capture_us."""
        opt = self.options
        i = opt.intrinsics
        index = self._index
        self._index += 1
        available = capture_us + int(round(opt.latency_ms * 1000))
        if index in opt.blank_frames:
            return KinectFrame(
                index,
                capture_us,
                available,
                np.zeros((i.height, i.width, 3), np.uint8),
                np.zeros((i.height, i.width), np.uint16),
                np.array(T_room_cam, float),
                True,
            )
        if self._native is not None:
            rgb, depth_mm = self._render_native(T_room_cam)
            return KinectFrame(
                index, capture_us, available, rgb, depth_mm, np.array(T_room_cam, float), False
            )
        z, pts, face = self.raycast(T_room_cam)
        rgb = self._shade(pts, face)  # (N, 3) view of (N, 4) texels
        if opt.rgb_noise_std > 0:
            # A seeded bank of noise frames, read at a random offset: per-frame Gaussian draws of
            # 0.9 M values cost more than the whole ray cast.
            noise = self._bank_slice(self._rgb_bank(), rgb.size).reshape(rgb.shape)
            noisy = np.add(rgb, noise, dtype=np.int16)
            rgb = np.clip(noisy, 0, 255, out=noisy).astype(np.uint8)
        else:
            rgb = np.ascontiguousarray(rgb)
        depth_m, missing = self._sensor_depth(z.reshape(i.height, i.width), copy=False)
        np.copyto(depth_m, 0, where=missing)
        depth_m *= np.float32(1000.0)
        depth_mm = np.round(depth_m, out=depth_m).astype(np.uint16)
        return KinectFrame(
            index,
            capture_us,
            available,
            rgb.reshape(i.height, i.width, 3),
            depth_mm,
            np.array(T_room_cam, float),
            False,
        )

    def _render_native(self, T_room_cam) -> tuple[np.ndarray, np.ndarray]:
        """The C++ back end's (rgb, depth_mm), drawing from self._rng exactly what the numpy path
        draws, in its order (RGB noise offset, depth noise offset, dropout uniforms)."""
        opt = self.options
        i = opt.intrinsics
        T, R, o = self._checked_pose(T_room_cam)
        rects = np.zeros((len(self.room.obstacles), 4), np.int32)  # r0 == r1: not visible
        for k, box in enumerate(self.room.obstacles):
            rect = self._screen_rect(box, R, o)
            if rect is not None:
                rects[k] = rect
        n = i.width * i.height
        rgb_noise = self._bank_slice(self._rgb_bank(), 3 * n) if opt.rgb_noise_std > 0 else None
        depth_noise = self._bank_slice(self._depth_bank(), n) if opt.depth_noise else None
        dropout_u = None
        if opt.dropout_fraction > 0:
            dropout_u = self._rng.random((i.height, i.width), dtype=np.float32)
        return self._native.render(T, rects, opt, rgb_noise, depth_noise, dropout_u)

    def render_indexed(self, T_room_cam: np.ndarray, capture_us: int, index: int) -> KinectFrame:
        """Frame number `index` as a pure function of (room, options, pose, index), whatever was
        rendered before: its noise comes from a generator seeded by (options.seed, index) (and
        the noise banks, which depend on the seed only). The live emulator renders this way so
        that any delivered frame can be re-rendered bit for bit afterwards. Does not touch the
        sequential stream `render` draws from."""
        if index < 0:
            raise ValueError(f"frame index must be >= 0, got {index}")
        seq_rng, seq_index = self._rng, self._index
        self._rng = np.random.default_rng((self.options.seed, index))
        self._index = index
        try:
            return self.render(T_room_cam, capture_us)
        finally:
            self._rng, self._index = seq_rng, seq_index

    def _rgb_bank(self) -> np.ndarray:
        """4 frames of rounded Gaussian RGB noise (int16), from the seed's bank stream."""
        if self._rgb_noise_bank is None:
            i = self.options.intrinsics
            g = np.random.default_rng((self.options.seed, NOISE_BANK_STREAM, 0))
            n = i.height * i.width * 3 * NOISE_BANK_FRAMES
            self._rgb_noise_bank = np.round(
                g.standard_normal(n, dtype=np.float32) * self.options.rgb_noise_std
            ).astype(np.int16)
        return self._rgb_noise_bank

    def _depth_bank(self) -> np.ndarray:
        """4 frames of standard normal draws (float32) for the depth noise."""
        if self._depth_noise_bank is None:
            i = self.options.intrinsics
            g = np.random.default_rng((self.options.seed, NOISE_BANK_STREAM, 1))
            n = i.height * i.width * NOISE_BANK_FRAMES
            self._depth_noise_bank = g.standard_normal(n, dtype=np.float32)
        return self._depth_noise_bank

    def _bank_slice(self, bank: np.ndarray, n: int) -> np.ndarray:
        """n consecutive bank values from a random offset (self._rng); a fresh draw of the same
        distribution when n is more than half the bank (offsets would barely vary)."""
        if 2 * n > bank.size:
            if bank.dtype == np.float32:
                return self._rng.standard_normal(n, dtype=np.float32)
            scale = self.options.rgb_noise_std
            return np.round(self._rng.standard_normal(n, dtype=np.float32) * scale).astype(
                bank.dtype
            )
        off = int(self._rng.integers(0, bank.size - n))
        return bank[off : off + n]

    def sensor_depth(self, z_true_m: np.ndarray) -> np.ndarray:
        """Applies the Kinect error model to exact depth (m). Missing readings are NaN."""
        z, missing = self._sensor_depth(z_true_m, copy=True)
        np.copyto(z, np.nan, where=missing)
        return z

    def _sensor_depth(self, z_true_m: np.ndarray, copy: bool) -> tuple[np.ndarray, np.ndarray]:
        """(depth with noise and quantisation, float32; mask of pixels with no reading). Without
        `copy`, z_true_m (float32) is overwritten."""
        opt = self.options
        f32 = np.float32
        z = z_true_m.astype(f32, copy=copy)
        with np.errstate(invalid="ignore"):
            missing = ~(z >= f32(opt.min_range_m))  # also NaN and -inf
            missing |= z > f32(opt.max_range_m)  # also +inf
        if opt.shadows:
            missing |= self._projector_shadow(z)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if opt.depth_noise:
                # sigma_z = NOISE_COEFF_PER_M z^2 (Khoshelham & Elberink 2012)
                noise = self._bank_slice(self._depth_bank(), z.size).reshape(z.shape)
                noise = noise * f32(NOISE_COEFF_PER_M)
                noise *= z
                noise *= z
                z += noise
            if opt.quantise:
                k = f32(IR_FOCAL_PX * BASELINE_M * DISPARITY_SUBPIXELS)  # disparity (1/8 px) = k/z
                disparity = np.divide(k, z)
                np.round(disparity, out=disparity)
                np.divide(k, disparity, out=z)
        if opt.dropout_fraction > 0:
            missing |= self._rng.random(z.shape, dtype=f32) < f32(opt.dropout_fraction)
        return z, missing

    def _projector_shadow(self, z: np.ndarray) -> np.ndarray:
        """Pixels the projector cannot illuminate. The projector sits BASELINE_M to the camera's
        right (+x); a pixel at column u projects to projector column u - f b / z. Scanning from the
        right, a pixel is shadowed when a pixel to its right already projects at or left of it."""
        f32 = np.float32
        u = np.arange(z.shape[1], dtype=f32)
        with np.errstate(divide="ignore", invalid="ignore"):
            up = np.divide(f32(self.options.intrinsics.fx * BASELINE_M), z)
            np.subtract(u, up, out=up)
        rev = up[:, ::-1]  # scan right -> left
        prev_min = np.minimum.accumulate(rev, axis=1)
        shadow_rev = np.zeros(z.shape, bool)
        # Tolerance of a tenth of a pixel so a smooth surface never shadows itself by rounding.
        prev_min += f32(0.1)
        np.greater(rev[:, 1:], prev_min[:, :-1], out=shadow_rev[:, 1:])
        return shadow_rev[:, ::-1]

    def frames_due(self, t_from_us: int, t_to_us: int) -> list[int]:
        """Capture times in (t_from_us, t_to_us] on the fps grid (the sensor's free-running
        clock)."""
        p = self.options.frame_period_us
        first = (t_from_us // p + 1) * p
        return list(range(first, t_to_us + 1, p))
