"""Ten minutes, not ten seconds: a closed-loop flight with SLAM in the loop (hilrig.slam_flight: the
real rgbd-streamer fed by the live Kinect emulator, slam-server, quad-control, the real firmware in
simavr and the FC emulator) that takes off and flies a box of four waypoints over and over for
HIL_LONG_FLIGHT_MIN minutes (default 10), then lands.

What it shows, per minute of flight: every waypoint's true arrival error, the SLAM estimate's error
against the rendered camera poses (one rigid alignment over the whole flight, so drift shows as a
growing error), camera -> pose latency (the SLAM part of the camera -> PWM path, from
quad-control's flight log), and the resident memory of slam-server and quad-control. A system whose
back-end cost or memory grows with flight time, or whose estimate walks away, fails here where the
30-60 s scenarios pass. Targets: every waypoint within WAYPOINT_TOLERANCE_M, SLAM error <= 30 mm
in every minute, no SLAM map reset, the last minute's camera -> pose p95 <= 1.5x the second
minute's, slam-server's memory in the last minute <= 1.5x the second minute's.
Report: test-artifacts/hil/slam_long_flight.json (printed by make hil).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
from fc_emulator import QuadParams
from hilrig import missions
from hilrig.paths import artifacts_dir
from hilrig.slam_flight import SlamFlight, SlamFlightOptions, missing_parts
from hilrig.verdict import map_resets
from kinect_emulator.live import match_capture_stamps
from slam_study.se3 import align_rigid

pytestmark = pytest.mark.hil

FLIGHT_MIN = float(os.environ.get("HIL_LONG_FLIGHT_MIN", "10"))
# The box flown, floor frame (m) relative to the take-off point: the two waypoints of scenario 2 and
# their mirror, so the camera revisits the same views every lap (a bounded map must not grow).
BOX = ((1.0, 0.0), (1.0, 0.8), (0.0, 0.8), (0.0, 0.0))
WAYPOINT_TOLERANCE_M = 0.25  # as scenario 2: 0.15 m of quad-control's arrival + SLAM drift
SLAM_ERROR_LIMIT_M = 0.030  # the demo's SLAM ATE target, here in every minute
GROWTH_LIMIT = 1.5  # last minute vs second minute (the back-end p95 criterion)
# Indoor disturbances, as the other SLAM scenarios.
DISTURBED = QuadParams(
    gust_accel_std_mss=0.15, gust_tau_s=2.0, trim_error_deg=(0.5, -0.3), disturbance_seed=7
)


def _rss_mib(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def _gap_lines(qc) -> list[str]:
    """quad-control's explained command gaps (firmware_link.cpp, command_gap.hpp), the first 20."""
    if qc is None:
        return []
    return [
        ln.split("firmware link: ", 1)[1]
        for ln in qc.log_text().splitlines()
        if "without a command" in ln
    ][:20]


def _aligned_errors(est: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-sample position error after one rigid (Horn, no scale) alignment of est to gt."""
    rot, t = align_rigid(gt, est)
    return np.linalg.norm(est @ rot.T + t - gt, axis=1)


def _slam_error_by_minute(flight: SlamFlight, t0_us: int) -> list[dict]:
    tracked = [p for p in flight.poses() if p["tracking"] == "1"]
    stamps = [int(p["capture_us"]) for p in tracked]
    matched = match_capture_stamps(flight.kinect.records(), stamps)
    rows = [(s, p, r) for s, p, r in zip(stamps, tracked, matched, strict=False) if r is not None]
    if len(rows) < 10:
        return []
    est = np.array([[float(p["x_m"]), float(p["y_m"]), float(p["z_m"])] for _, p, _ in rows])
    gt = np.array([np.asarray(r.T_room_cam)[:3, 3] for _, _, r in rows])
    err = _aligned_errors(est, gt)
    minute = np.array([(s - t0_us) // 60_000_000 for s, _, _ in rows])
    out = []
    for m in range(int(minute.max()) + 1):
        e = err[minute == m]
        if len(e):
            out.append(
                {
                    "minute": m + 1,
                    "samples": int(len(e)),
                    "rms_m": round(float(np.sqrt((e**2).mean())), 4),
                    "max_m": round(float(e.max()), 4),
                }
            )
    return out


def _camera_to_pose_by_minute(flight: SlamFlight, t0_us: int) -> list[dict]:
    by_min: dict[int, list[float]] = {}
    for p in flight.poses():
        if p["tracking"] != "1":
            continue
        cap = int(p["capture_us"])
        by_min.setdefault(int((cap - t0_us) // 60_000_000), []).append(
            (int(p["pose_us"]) - cap) / 1e3
        )
    return [
        {
            "minute": m + 1,
            "frames": len(v),
            "median_ms": round(float(np.median(v)), 1),
            "p95_ms": round(float(np.percentile(v, 95)), 1),
        }
        for m, v in sorted(by_min.items())
        if m >= 0
    ]


def test_slam_long_flight_box_laps(tmp_path):
    missing = missing_parts()
    if missing:
        pytest.skip("not built / not installed: " + ", ".join(missing))
    with SlamFlight(tmp_path, SlamFlightOptions(quad_params=DISTURBED)) as flight:
        to = missions.take_off(flight, progress=print)
        start = to["start_room_m"]
        t0_us = int(
            time.monotonic() * 1e6
        )  # the flight log's capture stamps are CLOCK_MONOTONIC us
        t_end = time.monotonic() + FLIGHT_MIN * 60.0
        procs = {name: p for name, p in flight._procs if name in ("slam-server", "quad-control")}
        legs, rss = [], []
        lap, aborted = 0, None
        try:
            while time.monotonic() < t_end:
                lap += 1
                for x, y in BOX:
                    leg = missions.go_to(flight, start, x, y)
                    minute = int((time.monotonic() * 1e6 - t0_us) // 60_000_000) + 1
                    legs.append({"lap": lap, "minute": minute, "waypoint": [x, y], **leg})
                    rss.append(
                        {"minute": minute, **{n: _rss_mib(p.proc.pid) for n, p in procs.items()}}
                    )
                print(
                    f"lap {lap}: {len(legs)} waypoints, "
                    f"worst {max(leg['max_m'] for leg in legs):.3f} m, "
                    f"rss {rss[-1]}"
                )
            landing = missions.land(flight, progress=print)
        except (
            TimeoutError,
            RuntimeError,
        ) as e:  # the report is still written, then the test fails
            aborted = (
                f"after {len(legs)} waypoints, "
                f"{(time.monotonic() * 1e6 - t0_us) / 6e7:.1f} min: {e}"
            )
            landing = None
        state = flight.state()
        resets = map_resets(
            procs["slam-server"].log_text() if "slam-server" in procs else None,
            procs["quad-control"].log_text() if "quad-control" in procs else None,
            state,
        )
        slam_err = _slam_error_by_minute(flight, t0_us)
        latency = _camera_to_pose_by_minute(flight, t0_us)
        rss_by_min = {}
        for r in rss:
            rss_by_min[r["minute"]] = r  # the last sample of each minute
        report = {
            "flight_min": FLIGHT_MIN,
            "aborted": aborted,
            "laps": lap,
            "waypoints": len(legs),
            "worst_waypoint_m": round(max(leg["max_m"] for leg in legs), 3) if legs else None,
            "waypoints_by_minute": [
                {"minute": m, "n": len(v), "worst_m": round(max(leg["max_m"] for leg in v), 3)}
                for m in sorted({leg["minute"] for leg in legs})
                for v in [[leg for leg in legs if leg["minute"] == m]]
            ],
            "slam_error_by_minute": slam_err,
            "camera_to_pose_by_minute": latency,
            "rss_mib_by_minute": list(rss_by_min.values()),
            "landing": landing,
            "resets": resets,
            "failsafe_events": [e for _, e in flight.rig.fc.events if "failsafe" in e],
            # Command gaps: quad-control's own count and longest gap between two commands
            # (each gap over 100 ms is logged with its causes in quad-control.log), the firmware
            # link's timeouts, and the rig's side: simulated gaps between lines on the serial link.
            "command_gaps": {
                k: state.get("firmware", {}).get(k)
                for k in (
                    "command_gaps",
                    "max_command_gap_ms",
                    "timeouts",
                    "withheld",
                    "sent",
                    "ok",
                )
            },
            "command_gap_log": _gap_lines(procs.get("quad-control")),
            "rig_injection_gaps": flight.rig.injection_gaps[:20],
            "rig_lag_dropped_s": round(flight.rig.lag_dropped_s, 3),
            # SLAM's loop corrections as the controller saw them (PoseUpdate.map_correction_count):
            # declared jumps flown as re-anchors, those refused as too large, undeclared jumps
            # rejected.
            "map_corrections": {
                k: state.get(k)
                for k in (
                    "map_correction_count",
                    "map_resets",
                    "refused_map_corrections",
                    "rejected_poses",
                )
            },
            "realtime_factor": round(flight.rig.realtime_factor, 3),
            **flight.scores(),
        }
        (artifacts_dir() / "slam_long_flight.json").write_text(
            json.dumps(report, indent=2, default=str)
        )
        print("\nslam_long_flight:", json.dumps(report, default=str))

    assert aborted is None, aborted
    assert resets["resets"] == 0, resets
    assert not report["failsafe_events"], report["failsafe_events"]
    bad_legs = [leg for leg in legs if leg["max_m"] > WAYPOINT_TOLERANCE_M]
    assert not bad_legs, bad_legs[:5]
    assert slam_err and all(m["rms_m"] <= SLAM_ERROR_LIMIT_M for m in slam_err), slam_err
    # Whole minutes only: the landing's partial minute (a few dozen frames) would hide a growth.
    full = [m for m in latency if m["frames"] >= 0.5 * max(x["frames"] for x in latency)]
    if len(full) >= 3:
        assert full[-1]["p95_ms"] <= GROWTH_LIMIT * full[1]["p95_ms"], latency
    minutes = report["rss_mib_by_minute"]
    if len(minutes) >= 3 and minutes[1].get("slam-server") and minutes[-1].get("slam-server"):
        assert minutes[-1]["slam-server"] <= GROWTH_LIMIT * minutes[1]["slam-server"], minutes
