"""ctypes binding of the C++ Kinect renderer (hil/kinect_emulator/cpp, libkinect_render.so).

`make build` (CMake, hil/kinect_emulator/CMakeLists.txt) builds <build>/lib/libkinect_render.so;
<build> is RGBD_BUILD_DIR or <repo>/build, as for the rig's other build outputs. The library does
the per-pixel work of KinectEmulator.render (ray cast, texture, depth model); Python keeps the
random number generator and passes the same noise slices and dropout uniforms the numpy path would
draw, so the two back ends give the same images (tests/test_native.py) and a frame stays a pure
function of (pose, index).

Thread safety: a NativeRenderer may render from several threads at once (the library keeps no
per-frame state; scratch buffers are per thread).
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]
LIBRARY_NAME = "libkinect_render.so"
API_VERSION = 1  # KR_API_VERSION in kinect_render.h


def build_dir() -> Path:
    return Path(os.environ.get("RGBD_BUILD_DIR", REPO_ROOT / "build"))


def library_path() -> Path:
    return build_dir() / "lib" / LIBRARY_NAME


def expected_built() -> bool:
    """True when the configured build tree should contain the library: <build>/CMakeCache.txt
    exists and RGBD_BUILD_HIL is not OFF (the library is part of hil/). Tests use it to fail, not
    skip, when the library is missing from a build that was supposed to make it."""
    cache = build_dir() / "CMakeCache.txt"
    if not cache.is_file():
        return False
    for line in cache.read_text(errors="replace").splitlines():
        if line.startswith("RGBD_BUILD_HIL:"):
            return line.split("=", 1)[1].strip().upper() not in ("OFF", "0", "FALSE", "NO")
    return True


class _Sensor(ctypes.Structure):
    _fields_ = [
        ("min_range_m", ctypes.c_double),
        ("max_range_m", ctypes.c_double),
        ("shadows", ctypes.c_int),
        ("quantise", ctypes.c_int),
        ("depth_noise", ctypes.c_void_p),
        ("rgb_noise", ctypes.c_void_p),
        ("dropout_u", ctypes.c_void_p),
        ("dropout_fraction", ctypes.c_double),
    ]


_lib: ctypes.CDLL | None = None


def load_library(path: Path | None = None) -> ctypes.CDLL:
    """Loads (once) and checks the library. Raises OSError if missing or of another API version."""
    global _lib
    if _lib is not None:
        return _lib
    p = path or library_path()
    if not p.is_file():
        raise OSError(f"{p} not found (built by `make build`)")
    lib = ctypes.CDLL(str(p))
    lib.kr_api_version.restype = ctypes.c_int
    if lib.kr_api_version() != API_VERSION:
        raise OSError(f"{p}: API version {lib.kr_api_version()}, expected {API_VERSION} (rebuild)")
    dp = ctypes.POINTER(ctypes.c_double)
    lib.kr_create.restype = ctypes.c_void_p
    lib.kr_create.argtypes = [ctypes.c_int, ctypes.c_int] + [ctypes.c_double] * 4 + [
        dp, dp, ctypes.c_int, dp, ctypes.c_double, ctypes.c_double, ctypes.c_void_p,
        ctypes.c_int, ctypes.c_int, ctypes.c_int,
    ]  # fmt: skip
    lib.kr_destroy.restype = None
    lib.kr_destroy.argtypes = [ctypes.c_void_p]
    lib.kr_render.restype = ctypes.c_int
    lib.kr_render.argtypes = [
        ctypes.c_void_p, dp, ctypes.c_void_p, ctypes.POINTER(_Sensor), ctypes.c_void_p,
        ctypes.c_void_p,
    ]  # fmt: skip
    _lib = lib
    return lib


def _ptr(a: np.ndarray | None) -> int | None:
    return None if a is None else a.ctypes.data


class NativeRenderer:
    """One room + intrinsics in the C++ renderer. `tex_packed`: uint32 R | G << 8 | B << 16, C
    order, (N, H, W) (copied by the library)."""

    def __init__(self, room, intrinsics, tex_packed: np.ndarray, tex_shape: tuple[int, int, int]):
        self._lib = load_library()
        tex = np.ascontiguousarray(tex_packed, dtype=np.uint32)
        i = intrinsics
        self.width, self.height = i.width, i.height
        lo = (ctypes.c_double * 3)(*room.bounds.lo_m)
        hi = (ctypes.c_double * 3)(*room.bounds.hi_m)
        boxes = [v for b in room.obstacles for v in (*b.lo_m, *b.hi_m)]
        arr = (ctypes.c_double * max(1, len(boxes)))(*boxes)
        n, h, w = tex_shape
        self._handle = self._lib.kr_create(
            i.width, i.height, i.fx, i.fy, i.cx, i.cy, lo, hi, len(room.obstacles), arr,
            room.tile_w_m, room.tile_h_m, tex.ctypes.data, n, h, w,
        )  # fmt: skip
        if not self._handle:
            raise ValueError("kr_create rejected the room/intrinsics")

    def render(
        self,
        T_room_cam: np.ndarray,
        rects: np.ndarray,
        options,
        rgb_noise: np.ndarray | None,
        depth_noise: np.ndarray | None,
        dropout_u: np.ndarray | None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(rgb (H, W, 3) uint8, depth_mm (H, W) uint16). rects: (n_obstacles, 4) int32 rows r0, r1,
        c0, c1 (r0 == r1: not visible). Noise arrays: C-contiguous, one value per pixel (per
        channel for RGB), as KinectEmulator draws them."""
        T = np.ascontiguousarray(T_room_cam, dtype=np.float64)
        rects = np.ascontiguousarray(rects, dtype=np.int32)
        rgb_noise = None if rgb_noise is None else np.ascontiguousarray(rgb_noise, np.int16)
        depth_noise = None if depth_noise is None else np.ascontiguousarray(depth_noise, np.float32)
        dropout_u = None if dropout_u is None else np.ascontiguousarray(dropout_u, np.float32)
        npx = self.width * self.height
        for a, n in ((rgb_noise, 3 * npx), (depth_noise, npx), (dropout_u, npx)):
            if a is not None and a.size != n:
                raise ValueError(f"noise array of {a.size} values, expected {n}")
        sensor = _Sensor(
            options.min_range_m, options.max_range_m, int(options.shadows),
            int(options.quantise), _ptr(depth_noise), _ptr(rgb_noise), _ptr(dropout_u),
            options.dropout_fraction,
        )  # fmt: skip
        rgb = np.empty((self.height, self.width, 3), np.uint8)
        depth = np.empty((self.height, self.width), np.uint16)
        rc = self._lib.kr_render(
            self._handle, T.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), _ptr(rects),
            ctypes.byref(sensor), rgb.ctypes.data, depth.ctypes.data,
        )  # fmt: skip
        if rc != 0:
            raise ValueError(f"kr_render failed ({rc})")
        return rgb, depth

    def __del__(self) -> None:
        h, self._handle = getattr(self, "_handle", None), None
        if h:
            self._lib.kr_destroy(h)
