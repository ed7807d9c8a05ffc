"""Renderer child of soak.kinect_faults.FaultyLiveKinect: kinect_emulator's live child with the
renderer's frames replaced by blank or malformed ones where the request file (module
soak.kinect_faults) asks. Run as `python -m soak.kinect_fault_child` by FaultyLiveKinect only.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from kinect_emulator.live import _child_main
from kinect_emulator.renderer import KinectEmulator, KinectFrame

from soak.kinect_faults import FAULTS_ENV

# Rows of a malformed frame that carry garbage: 30-240 of 480, i.e. 1-8 of the ~32 rows of
# isochronous packets a frame spans per 15 rows (libfreenect: 1760-byte depth packets).
MALFORMED_ROWS_MIN, MALFORMED_ROWS_MAX = 30, 240
# Garbage depth: any 13-bit mm value, so also beyond the Kinect's 4.5 m and below its 0.5 m.
MALFORMED_DEPTH_MAX_MM = 8191


class _Requests:
    """The request file, read again whenever it grew; each line's frames are used up in order."""

    def __init__(self, path: str | None) -> None:
        self.path = Path(path) if path else None
        self.done_path = self.path.parent / "camera-faults-done.txt" if self.path else None
        self.size = 0
        self.pending: list[list] = []  # [kind, t_mono_s, frames left]

    def take(self, t_mono_s: float) -> str | None:
        if self.path is None:
            return None
        try:
            size = self.path.stat().st_size
        except OSError:
            return None
        if size > self.size:
            with open(self.path) as f:
                f.seek(self.size)
                for line in f.read(size - self.size).splitlines():
                    words = line.split()
                    if len(words) == 3:
                        self.pending.append([words[0], float(words[1]), int(words[2])])
            self.size = size
        for req in self.pending:
            if req[2] > 0 and t_mono_s >= req[1]:
                req[2] -= 1
                return req[0]
        return None


def _malformed(frame: KinectFrame) -> KinectFrame:
    rng = np.random.default_rng(frame.index)
    h, w = frame.depth_mm.shape
    rows = int(rng.integers(MALFORMED_ROWS_MIN, MALFORMED_ROWS_MAX + 1))
    top = int(rng.integers(0, h - rows + 1))
    depth = frame.depth_mm.copy()
    rgb = frame.rgb.copy()
    depth[top : top + rows] = rng.integers(0, MALFORMED_DEPTH_MAX_MM + 1, (rows, w), np.uint16)
    rgb[top : top + rows] = rng.integers(0, 256, (rows, w, 3), np.uint8)
    return KinectFrame(
        frame.index, frame.capture_us, frame.available_us, rgb, depth, frame.T_room_cam, False
    )


def main() -> int:
    requests = _Requests(os.environ.get(FAULTS_ENV))
    render = KinectEmulator.render_indexed

    def render_indexed(self, T_room_cam, capture_us, index):
        frame = render(self, T_room_cam, capture_us, index)
        kind = requests.take(capture_us / 1e6)
        if kind is None:
            return frame
        with open(requests.done_path, "a") as f:
            f.write(f"{kind} {index} {capture_us / 1e6:.6f}\n")
        if kind == "blank":
            return KinectFrame(
                frame.index,
                frame.capture_us,
                frame.available_us,
                np.zeros_like(frame.rgb),
                np.zeros_like(frame.depth_mm),
                frame.T_room_cam,
                True,
            )
        return _malformed(frame)

    KinectEmulator.render_indexed = render_indexed
    return _child_main()


if __name__ == "__main__":
    raise SystemExit(main())
