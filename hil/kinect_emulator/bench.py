"""Kinect emulator speed: render time per 640x480 RGB-D frame of each back end (numpy and the C++
library, when built) on the same poses, and TUM-folder write time; with
--live, the LiveKinect renderer child fed at --fps for --seconds with a reader that consumes the
FIFO index like fakenect (line, then its files), and the cost of submit() in the calling thread.

    .venv/bin/python hil/kinect_emulator/bench.py [--frames N] [--renderer numpy|cpp|both]
    .venv/bin/python hil/kinect_emulator/bench.py --live [--fps 30] [--seconds 5]
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


def _pose(i: int, fps: float) -> np.ndarray:
    """A 1.5 m circle at 0.5 rad/s, yawing with the heading (stays inside the default room)."""
    a = 0.5 * i / fps
    return camera_pose_from_ned(
        [1.5 * np.sin(a), 1.5 - 1.5 * np.cos(a), -1.7], 0.02, -0.03, a, 30.0,
        origin_room_m=(-0.5, 1.5, 0.2),
    )  # fmt: skip


def live(fps: float, seconds: float, renderer: str) -> int:
    import os
    import threading

    from kinect_emulator.live import INDEX_NAME, LiveKinect

    def reader(dump: Path) -> None:
        with open(dump / INDEX_NAME, "rb") as f:
            for line in f:
                (dump / line.decode().strip()).read_bytes()

    with tempfile.TemporaryDirectory() as d:
        cam = LiveKinect(Path(d) / "live", KinectOptions(seed=1, fps=fps, renderer=renderer))
        cam.start()
        t = threading.Thread(target=reader, args=(Path(d) / "live",), daemon=True)
        t.start()
        submit_us = []
        n = int(fps * seconds)
        t0 = time.monotonic()
        for i in range(n):
            time.sleep(max(0.0, t0 + i / fps - time.monotonic()))
            a = time.perf_counter()
            cam.submit(time.monotonic(), _pose(i, fps))
            submit_us.append((time.perf_counter() - a) * 1e6)
        flown = time.monotonic() - t0
        time.sleep(0.2)
        cam.close()
        t.join(5)
        st = cam.stats()
        recs = cam.records()
    lat = np.array([(r.index_written_mono_s - r.t_mono_s) * 1e3 for r in recs])
    print(
        f"live kinect ({st.get('renderer', '?')} renderer): {n} requests at {fps:g} fps over"
        f" {flown:.1f} s, load {os.getloadavg()}"
    )
    print(
        f"  render (child) median {st['render_ms_median']:6.1f} ms  p95 {st['render_ms_p95']:6.1f}"
        f" ms; delivered {st['delivered']} ({st['delivered'] / flown:.1f} fps), superseded"
        f" {st['superseded']}, reader behind {st['reader_behind']}, errors {st['errors']}"
    )
    print(
        f"  exposure -> INDEX written median {np.median(lat):6.1f} ms  p95"
        f" {np.percentile(lat, 95):6.1f} ms"
    )
    print(
        f"  submit() in the caller median {np.median(submit_us):6.0f} us  max"
        f" {np.max(submit_us):6.0f} us"
    )
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description="time the Kinect emulator (render + write)")
    ap.add_argument("--frames", type=int, default=60, help="frames to render (default 60)")
    ap.add_argument("--live", action="store_true", help="time LiveKinect (renderer child)")
    ap.add_argument("--fps", type=float, default=30.0, help="--live request rate (default 30)")
    ap.add_argument("--seconds", type=float, default=5.0, help="--live duration (default 5)")
    ap.add_argument(
        "--renderer", choices=("numpy", "cpp", "both"), default="both",
        help="back end(s) to time (default both; --live: cpp when built unless numpy)",
    )  # fmt: skip
    args = ap.parse_args()
    if args.frames < 1:
        print("bench: --frames must be >= 1", file=sys.stderr)
        return 2
    if args.live:
        if not (0 < args.fps <= 120 and 0 < args.seconds <= 600):
            print("bench: need 0 < --fps <= 120 and 0 < --seconds <= 600", file=sys.stderr)
            return 2
        return live(args.fps, args.seconds, "auto" if args.renderer == "both" else args.renderer)
    import os

    from kinect_emulator import native

    room = default_room()
    backends = ["numpy", "cpp"] if args.renderer == "both" else [args.renderer]
    if "cpp" in backends and not native.library_path().is_file():
        print(f"bench: {native.library_path()} not built (make build); timing numpy only")
        backends = [b for b in backends if b != "cpp"] or ["numpy"]
    print(f"kinect emulator: {args.frames} frames 640x480, load average {os.getloadavg()}")
    for backend in backends:
        emu = KinectEmulator(room, KinectOptions(seed=1, renderer=backend))
        render_ms, cpu_ms, write_ms = [], [], []
        with tempfile.TemporaryDirectory() as d, TumFolderWriter(Path(d) / "seq") as w:
            for i in range(args.frames):
                T = _pose(i, 30.0)
                c0, t0 = time.process_time(), time.perf_counter()
                f = emu.render(T, i * 33333)
                t1, c1 = time.perf_counter(), time.process_time()
                if backend == backends[-1]:
                    w.write(f)
                t2 = time.perf_counter()
                render_ms.append((t1 - t0) * 1e3)
                cpu_ms.append((c1 - c0) * 1e3)
                write_ms.append((t2 - t1) * 1e3)
        r = np.array(render_ms[1:] or render_ms)  # the first frame builds the noise banks
        c = np.array(cpu_ms[1:] or cpu_ms)
        print(
            f"  render {backend:5s} median {np.median(r):6.1f} ms  p95 {np.percentile(r, 95):6.1f}"
            f" ms  (CPU median {np.median(c):5.1f} ms)  -> {1000 / np.median(r):6.1f} fps"
        )
    wr = np.array(write_ms)
    print(f"  TUM write    median {np.median(wr):6.1f} ms  p95 {np.percentile(wr, 95):6.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
