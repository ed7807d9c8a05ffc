"""`make demo`: HIL scenario 2 end to end - a simulated flight with SLAM in the loop.

The real rgbd-streamer (fed by the live Kinect emulator through fakenect), slam-server and
quad-control fly the real firmware image in simavr and the flight-controller emulator: take off,
hold at 1.7 m, fly to two waypoints, land. The dashboard is up during the flight (the address is
printed; open it in a browser to watch). At the end: ATE of the SLAM trajectory against the
emulator's truth, latency per stage, hold and waypoint errors, touchdown speed, and a PASS/MISS
line per target (hilrig.verdict: hold and each waypoint +-0.15 m, touchdown <= 0.5 m/s, SLAM ATE
<= 30 mm, 0 SLAM map resets counted from the processes' logs and quad-control's state, the rig
in real time). Exit status: 0 all targets met, 1 a target missed (each miss says why), 2 cannot fly.
Output: out/demo-hil/ (report.json with the verdict, flight-log/, the processes' logs).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

from hilrig import missions
from hilrig.paths import REPO_ROOT
from hilrig.slam_flight import SlamFlight, SlamFlightOptions, missing_parts
from hilrig.verdict import judge, map_resets


def frame_rate_guide(out: Path, fps: float) -> str:
    """The study's frame-rate guide for the flight just flown: the camera's measured velocities
    (emulator truth, out/groundtruth.tum) -> the guide's predicted error at the rate flown and its
    recommended rate (slam_study.guide.flight_summary, docs/study.md). Informational only."""
    try:
        from slam_study.guide import flight_summary

        return flight_summary(out / "groundtruth.tum", fps)
    except Exception as e:  # noqa: BLE001 - one summary line must not fail the demo
        return f"frame-rate guide not available: {e}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--out", type=Path, default=REPO_ROOT / "out" / "demo-hil", help="output folder (replaced)"
    )
    ap.add_argument(
        "--fps",
        type=float,
        default=SlamFlightOptions.fps,
        help=f"camera frame rate (default {SlamFlightOptions.fps:g})",
    )
    ap.add_argument(
        "--hold-s", type=float, default=10.0, help="seconds to hold before the waypoints"
    )
    ap.add_argument(
        "--linger-s", type=float, default=0.0, help="keep everything up this long after landing"
    )
    ap.add_argument(
        "--send-on-pose",
        choices=("on", "off"),
        default=None,
        help="quad-control's firmware.send_on_pose (default: its configured default)",
    )
    ap.add_argument(
        "--record",
        choices=("on", "off"),
        default="on",
        help="quad-control records the flight as MCAP in OUT/recording (default on; off "
        "measures what recording costs the loop)",
    )
    args = ap.parse_args(argv)
    missing = missing_parts()
    if missing:
        print("demo: cannot fly, not built / not installed: " + ", ".join(missing), file=sys.stderr)
        return 2
    if args.out.exists():
        shutil.rmtree(args.out)
    t0 = time.monotonic()

    def progress(text: str) -> None:
        print(f"demo [{time.monotonic() - t0:6.1f} s] {text}", flush=True)

    send_on_pose = None if args.send_on_pose is None else args.send_on_pose == "on"
    with SlamFlight(
        args.out,
        SlamFlightOptions(fps=args.fps, send_on_pose=send_on_pose, record=args.record == "on"),
    ) as flight:
        progress(
            f"dashboard: http://127.0.0.1:{flight.dashboard_port}/ (open it to watch the flight)"
        )
        progress(f"logs: {args.out}/*.log, flight log: {flight.log_dir}")
        try:
            report = missions.scenario2(flight, hold_s=args.hold_s, progress=progress)
        except (TimeoutError, RuntimeError) as e:
            # The flight did not go as planned: say why and how it ended, with the figures so far.
            progress(f"mission aborted: {e}")
            flight.hold_for(2.0)
            snap = flight.rig.snapshot()
            report = {
                "aborted": str(e),
                "armed_at_end": snap.armed,
                "landed_at_end": snap.landed,
                "touchdowns_mps": list(flight.rig.fc.touchdowns_mps),
                "fc_events": [e for _, e in flight.rig.fc.events],
                "realtime_factor": round(flight.rig.realtime_factor, 3),
            }
        report.update(flight.scores())
        try:  # quad-control's own account of its SLAM link (sessions, resumes, disconnects)
            final_state = flight.state()
        except Exception as e:  # noqa: BLE001 - quad-control may have died; the logs still count
            final_state = None
            progress(f"quad-control state not available at the end: {e}")
        if args.linger_s > 0:
            progress(f"landed; everything stays up {args.linger_s:.0f} s more")
            flight.hold_for(args.linger_s)
    resets = map_resets(
        _read(args.out / "slam-server.log"), _read(args.out / "quad-control.log"), final_state
    )
    report["slam_link"] = dict(resets, state=(final_state or {}).get("slam"))
    checks = judge(report, resets, args.fps)
    report["verdict"] = [c.__dict__ for c in checks]
    (args.out / "report.json").write_text(json.dumps(report, indent=2, default=str))
    print_figures(report, args)
    print("demo: ===== verdict =====")
    for c in checks:
        print(f"demo: {c.line()}")
    missed = [c.target for c in checks if not c.passed]
    if missed:
        print(f"demo: FAILED: {len(missed)} of {len(checks)} targets missed: {', '.join(missed)}")
        return 1
    print(f"demo: PASSED: all {len(checks)} targets met")
    return 0


def _read(path: Path) -> str | None:
    return path.read_text(errors="replace") if path.exists() else None


def print_figures(report: dict, args) -> None:
    if "aborted" in report:
        print("demo: ===== the flight did NOT complete (HIL scenario 2, SLAM in the loop) =====")
        print(f"demo: {report['aborted'][:400]}")
        print(
            f"demo: at the end: armed={report['armed_at_end']} landed={report['landed_at_end']}, "
            f"touchdowns {report['touchdowns_mps']} m/s, APM events {report['fc_events']}"
        )
        print(
            f"demo: SLAM ATE {report['ate']}; report {args.out / 'report.json'}; logs in {args.out}"
        )
        return
    a, lat, land = report["ate"], report["latency_ms"], report["landing"]
    print("demo: ===== summary (HIL scenario 2, SLAM in the loop) =====")
    if "ate_rmse_m" in a:
        print(
            f"demo: SLAM ATE RMSE {a['ate_rmse_m'] * 1000:.1f} mm "
            f"(max {a['ate_max_m'] * 1000:.1f} mm, "
            f"{a['pairs']} poses) against the emulator's truth"
        )
    else:
        print(f"demo: SLAM ATE not available: {a}")
    h = report["hold"]
    print(
        f"demo: hold at {missions.HOLD_HEIGHT_M} m: max error {h['max_m']:.3f} m, "
        f"RMS {h['rms_m']:.3f} m"
    )
    for i, w in enumerate(report["waypoints"], 1):
        print(f"demo: waypoint {i}: reached in {w['leg_s']} s, position error {w['max_m']:.3f} m")
    print(
        f"demo: landing: touchdown {land['touchdown_vertical_speed_mps']} m/s, "
        f"final distance to the last waypoint {report['final_distance_to_last_waypoint_m']} m"
    )
    if "capture_to_pwm" in lat:
        stages = [k for k in lat if k not in ("frames", "capture_to_pwm", "exposure_to_pwm")]
        print(
            "demo: latency, median ms: "
            + ", ".join(f"{k.replace('_to_', '->')} {lat[k]['median_ms']}" for k in stages)
        )
        print(
            f"demo: camera (capture stamp) -> PWM median {lat['capture_to_pwm']['median_ms']} ms "
            f"(p95 {lat['capture_to_pwm']['p95_ms']}) over {lat['frames']} frames "
            f"at {args.fps:g} fps"
        )
    s = report["stream"]
    print(
        f"demo: stream {s['received_fps']} fps received, "
        f"{s['slam_tracked']}/{s['slam_results']} SLAM results tracked"
    )
    print(f"demo: {frame_rate_guide(args.out, args.fps)}")
    link = report["slam_link"]
    print(
        f"demo: SLAM link: {link['link_breaks']} break(s), {link['resumes']} resumed, "
        f"resets {link['resets']} (counted from {', '.join(link['sources']) or 'nothing'})"
    )
    for proc, threads in (report.get("thread_cpu_s") or {}).items():
        busiest = ", ".join(f"{name} {cpu_s:.1f}" for name, cpu_s in list(threads.items())[:6])
        print(f"demo: CPU s by thread, {proc}: {busiest}")
    print(
        f"demo: report {args.out / 'report.json'}; {report['wall_s']} s, "
        f"real-time factor {report['realtime_factor']}"
    )
    print(
        f"demo: load average {report.get('load_average')}; "
        f"send_on_pose {args.send_on_pose or 'default'}; "
        f"recording {args.record}; "
        f"scheduling {report.get('scheduling')}"
    )


if __name__ == "__main__":
    sys.exit(main())
