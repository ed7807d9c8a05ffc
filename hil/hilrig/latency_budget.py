"""Prints the end-to-end latency budget from what the HIL scenarios measured.

    .venv/bin/python hil/hilrig/latency_budget.py [test-artifacts/hil]
Stages (thesis Table 4.22: 139 ms at 6 fps, 187 ms at 8 fps, camera -> PWM): capture -> stream
(rgbd-streamer, fakenect source, raw encodings, loopback), SLAM per frame (slam-eval front end on
emulated frames), PID (quad-control; not in the loop yet), HTTP -> firmware -> PWM (live rig).
A stage without a measurement is printed as such, never guessed; the one derived figure (frame age)
is labelled and left out of the sum.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def _load(d: Path, name: str) -> dict:
    p = d / name
    return json.loads(p.read_text()) if p.exists() else {}


def budget(d: Path) -> list[tuple[str, float | None, str]]:
    stream, slam, hold = (
        _load(d, "stream.json"),
        _load(d, "slam_replay.json"),
        _load(d, "scenario1_hold.json"),
    )
    frame_period_ms = 1000.0 / 30.0
    rows = [
        (
            "capture -> received at ground station",
            stream.get("capture_to_receive_median_ms"),
            "fakenect -> rgbd-streamer -> receiver (raw, loopback)",
        ),
        (
            "  + frame age at capture (derived, not summed)",
            frame_period_ms / 2,
            "Kinect 30 fps: half a frame period on average",
        ),
        (
            "SLAM front end per frame",
            slam.get("frontend_median_ms"),
            "slam-eval ORB on emulated frames",
        ),
        ("PID + command out (quad-control)", None, "not in the loop yet"),
        (
            "HTTP PUT -> bridge -> firmware -> reply (round trip)",
            hold.get("http_round_trip_median_ms"),
            "ground-station stand-in, live rig; an upper bound: the command acts before the "
            "reply returns",
        ),
        (
            "  of which serial in + firmware + reply out (not summed)",
            hold.get("serial_and_firmware_median_ms"),
            "simavr, simulated time",
        ),
        (
            "firmware reply -> next PWM frame",
            hold.get("reply_to_next_pwm_frame_median_ms"),
            "simavr, simulated time (50 Hz RC frame)",
        ),
    ]
    return rows


def main() -> int:
    d = (
        Path(sys.argv[1])
        if len(sys.argv) > 1
        else Path(__file__).resolve().parents[2] / "test-artifacts/hil"
    )
    rows = budget(d)
    print("latency budget (median ms per stage; thesis Table 4.22: 139 ms @ 6 fps, 187 ms @ 8 fps)")
    total, missing = 0.0, []
    for name, ms, how in rows:
        if ms is None:
            missing.append(name.strip())
            print(f"  {name:48s}      -   ({how})")
        else:
            print(f"  {name:48s} {ms:7.1f}   ({how})")
            if not name.startswith("  "):
                total += ms
    print(
        f"  {'sum of measured stages':48s} {total:7.1f}"
        + (f"   (missing: {', '.join(missing)})" if missing else "")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
