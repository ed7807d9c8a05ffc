"""Writes emulated Kinect frames where the real rgbd-streamer's capture sources read them.

* TumFolderWriter: a TUM RGB-D benchmark folder (rgb.txt, depth.txt, groundtruth.txt, rgb/*.png,
  depth/*.png with 5000 units per metre) that onboard/capture's TumReplaySource replays, and that
  slam-eval / tum-score score against groundtruth.txt.
* FakenectDumpWriter: a libfreenect "fakenect" dump (INDEX.txt, r-*.ppm, d-*.pgm) that the real
  libfreenect API replays (`fakenect <dir> rgbd-streamer --source freenect
  --freenect-disparity-depth`).
  Depth is stored as 11-bit raw disparity, the format fakenect-record writes; fakenect copies the
  bytes after the PGM header verbatim into the depth buffer, so the samples are in HOST order
  (little-endian here), not the big-endian the PGM format specifies.
Timestamps are the frames' simulated capture times (seconds, 6 decimals) offset by `t0_s`, so they
look like the benchmark's. Blank frames are written as they are (all-zero), as a real dump would be.
Not thread-safe; files are complete after `close()` (also on `with` exit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rgbd_protocol.tum_cameras import TUM_DEPTH_UNITS_PER_M  # noqa: F401  (re-exported)

from kinect_emulator.poses import rotation_to_quaternion_xyzw
from kinect_emulator.renderer import KinectFrame

# Raw 11-bit disparity <-> metres, libfreenect's documented approximation (Stephane Magnenat):
#   z_m = 0.1236 * tan(raw / 2842.5 + 1.1863); 2047 = no reading.
FREENECT_NO_READING = 2047
# Beyond ~10 m the approximation saturates (raw ~1050 of 2047); the v1 never reports such ranges.
FREENECT_MAX_DEPTH_MM = 10000


def depth_mm_to_freenect_raw(depth_mm: np.ndarray) -> np.ndarray:
    z = depth_mm.astype(np.float64) / 1000.0
    with np.errstate(divide="ignore", invalid="ignore"):
        raw = np.round((np.arctan(z / 0.1236) - 1.1863) * 2842.5)
    raw = np.where(
        (depth_mm > 0)
        & (depth_mm <= FREENECT_MAX_DEPTH_MM)
        & np.isfinite(raw)
        & (raw >= 0)
        & (raw < FREENECT_NO_READING),
        raw,
        FREENECT_NO_READING,
    )
    return raw.astype(np.uint16)


def freenect_raw_to_depth_mm(raw: np.ndarray) -> np.ndarray:
    """What onboard/capture's FreenectSource::disparity_to_mm makes of raw disparity (same fit,
    same rounding half away from zero, 0 for no reading or beyond 10 m)."""
    r = raw.astype(np.float64)
    z = 0.1236 * np.tan(r / 2842.5 + 1.1863)
    ok = (raw < FREENECT_NO_READING) & (z > 0) & (z <= FREENECT_MAX_DEPTH_MM / 1000.0)
    return np.where(ok, np.floor(z * 1000.0 + 0.5), 0).astype(np.uint16)


class TumFolderWriter:
    def __init__(self, directory, t0_s: float = 1_000_000_000.0) -> None:
        self.dir = Path(directory)
        (self.dir / "rgb").mkdir(parents=True, exist_ok=True)
        (self.dir / "depth").mkdir(parents=True, exist_ok=True)
        self.t0_s = t0_s
        self._rgb = open(self.dir / "rgb.txt", "w")
        self._depth = open(self.dir / "depth.txt", "w")
        self._gt = open(self.dir / "groundtruth.txt", "w")
        for f, what in (
            (self._rgb, "color images"),
            (self._depth, "depth maps"),
            (self._gt, "ground truth trajectory"),
        ):
            f.write(f"# {what} (emulated Kinect, hil/kinect_emulator)\n")
        self._gt.write("# timestamp tx ty tz qx qy qz qw\n")
        self.count = 0

    def write(self, frame: KinectFrame) -> str:
        """Writes one frame; returns its timestamp string."""
        from PIL import Image

        ts = f"{self.t0_s + frame.capture_us * 1e-6:.6f}"
        Image.fromarray(frame.rgb, "RGB").save(self.dir / "rgb" / f"{ts}.png", compress_level=1)
        d = np.minimum(frame.depth_mm.astype(np.uint32) * TUM_DEPTH_UNITS_PER_M // 1000, 65535)
        Image.fromarray(d.astype(np.uint16)).save(
            self.dir / "depth" / f"{ts}.png", compress_level=1
        )
        self._rgb.write(f"{ts} rgb/{ts}.png\n")
        self._depth.write(f"{ts} depth/{ts}.png\n")
        t = frame.T_room_cam[:3, 3]
        q = rotation_to_quaternion_xyzw(frame.T_room_cam[:3, :3])
        self._gt.write(
            f"{ts} {t[0]:.6f} {t[1]:.6f} {t[2]:.6f} {q[0]:.6f} {q[1]:.6f} {q[2]:.6f} {q[3]:.6f}\n"
        )
        self.count += 1
        return ts

    def close(self) -> None:
        for f in (self._rgb, self._depth, self._gt):
            f.close()

    def __enter__(self) -> "TumFolderWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class FakenectDumpWriter:
    def __init__(self, directory, t0_s: float = 0.0) -> None:
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.t0_s = t0_s
        self._index = open(self.dir / "INDEX.txt", "w")
        self.count = 0

    def write(self, frame: KinectFrame) -> None:
        t = self.t0_s + frame.capture_us * 1e-6
        h, w = frame.depth_mm.shape
        # fakenect names: <type>-<seconds since start>-<timestamp>-<frame>; the middle field is the
        # wall time fakenect paces by, the second the device timestamp (60 MHz ticks in real dumps).
        stamp = int(frame.capture_us * 60) & 0xFFFFFFFF
        dname = f"d-{t:.6f}-{stamp}-{frame.index}.pgm"
        rname = f"r-{t:.6f}-{stamp}-{frame.index}.ppm"
        raw = depth_mm_to_freenect_raw(frame.depth_mm)
        with open(self.dir / dname, "wb") as f:
            f.write(f"P5 {w} {h} 65535\n".encode())
            f.write(
                raw.astype("=u2").tobytes()
            )  # host order: what fakenect-record writes and reads
        with open(self.dir / rname, "wb") as f:
            f.write(f"P6 {w} {h} 255\n".encode())
            f.write(np.ascontiguousarray(frame.rgb).tobytes())
        self._index.write(dname + "\n" + rname + "\n")
        self.count += 1

    def close(self) -> None:
        self._index.close()

    def __enter__(self) -> "FakenectDumpWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
