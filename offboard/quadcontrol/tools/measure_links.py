"""Prints quad-control's link figures over a fixed run: firmware command rate/latency/timeouts
(firmware double behind the control link's WiFi-bridge emulator, loopback), stream fps, SLAM
latency and drops, on the TUM replay. A benchmark: it prints numbers and asserts nothing.

    .venv/bin/python offboard/quadcontrol/tools/measure_links.py [--seconds 20] \
        [--bin build/bin/quad-control]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
import urllib.request

REPO = pathlib.Path(__file__).resolve().parents[3]
sys.path[:0] = [str(REPO / "offboard/quadcontrol"), str(REPO / "protocol/python")]

from quadcontrol_harness.firmware_double import FirmwareDouble  # noqa: E402
from quadcontrol_harness.quad_control import KEY, QuadControl, write_config  # noqa: E402
from rgbd_protocol.control_bridge import WifiBridgeEmulator  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="measurement window (default 20)")
    ap.add_argument(
        "--bin", default=str(REPO / "build/bin/quad-control"), help="quad-control binary"
    )
    args = ap.parse_args()
    double = FirmwareDouble(KEY)
    bridge = WifiBridgeEmulator(double.transact).start()
    tmp = pathlib.Path("/tmp") / f"qc-measure-{time.time_ns()}"
    tmp.mkdir()
    qc = QuadControl(
        pathlib.Path(args.bin), ["--config", str(write_config(tmp, bridge.port)), "--port", "0"]
    )
    try:

        def state() -> dict:
            with urllib.request.urlopen(qc.url + "api/state", timeout=5) as r:
                return json.load(r)

        time.sleep(3)  # start-up: first frames, SLAM set-up
        a = state()
        t0 = time.monotonic()
        time.sleep(args.seconds)
        b = state()
        dt = time.monotonic() - t0
        fa, fb = a["firmware"], b["firmware"]
        print(f"window {dt:.1f} s on {b['stream']['source']}")
        print(
            f"firmware: {(fb['sent'] - fa['sent']) / dt:.1f} requests/s sent, "
            f"{(fb['ok'] - fa['ok']) / dt:.1f} accepted/s, "
            f"timeouts {fb['timeouts'] - fa['timeouts']}, stale {fb['stale'] - fa['stale']}, "
            f"errors {fb['http_errors'] - fa['http_errors']}, "
            f"latency last {fb['latency_ms']:.1f} ms, "
            f"mean {fb['mean_latency_ms']:.1f} ms"
        )
        print(
            f"stream: {(b['stream']['frames'] - a['stream']['frames']) / dt:.1f} frames/s "
            "received, "
            f"fps counter {b['stream']['fps']:.1f}, load+decode {b['stream']['latency_ms']:.1f} ms"
        )
        sa, sb = a["slam"], b["slam"]
        print(
            f"slam: {(sb['processed'] - sa['processed']) / dt:.2f} poses/s, dropped busy "
            f"{sb['dropped_busy'] - sa['dropped_busy']}, last latency {sb['latency_ms']:.0f} ms, "
            f"inliers {sb['inliers']}"
        )
        print(
            f"firmware double accepted {len(double.accepted)} commands, rejected {double.rejected}"
        )
    finally:
        qc.stop()
        bridge.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
