"""Kinect emulator speed: render time per 640x480 RGB-D frame and TUM-folder write time.

    .venv/bin/python hil/kinect_emulator/bench.py [--frames N]
Prints figures only (no pass/fail): on a shared 2-core machine the numbers depend on the load.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from kinect_emulator import (
    KinectEmulator,
    KinectOptions,
    TumFolderWriter,  # noqa: E402
    camera_pose_from_ned,
    default_room,
)


def main() -> int:
    ap = argparse.ArgumentParser(description="time the Kinect emulator (render + write)")
    ap.add_argument("--frames", type=int, default=60, help="frames to render (default 60)")
    args = ap.parse_args()
    if args.frames < 1:
        print("bench: --frames must be >= 1", file=sys.stderr)
        return 2
    emu = KinectEmulator(default_room(), KinectOptions(seed=1))
    render_ms, write_ms = [], []
    with tempfile.TemporaryDirectory() as d, TumFolderWriter(Path(d) / "seq") as w:
        for i in range(args.frames):
            T = camera_pose_from_ned(
                [0.02 * i, 0.0, -1.7], 0.02, -0.03, 0.01 * i, 30.0, origin_room_m=(-1.5, 0.5, 0.2)
            )
            t0 = time.perf_counter()
            f = emu.render(T, i * 33333)
            t1 = time.perf_counter()
            w.write(f)
            t2 = time.perf_counter()
            render_ms.append((t1 - t0) * 1e3)
            write_ms.append((t2 - t1) * 1e3)
    r = np.array(render_ms[1:] or render_ms)
    wr = np.array(write_ms)
    print(f"kinect emulator: {args.frames} frames 640x480")
    print(
        f"  render      median {np.median(r):6.1f} ms  p95 {np.percentile(r, 95):6.1f} ms"
        f"  -> {1000 / np.median(r):5.1f} fps"
    )
    print(f"  TUM write   median {np.median(wr):6.1f} ms  p95 {np.percentile(wr, 95):6.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
