"""Pass/fail of a closed-loop flight against the project's targets (`make demo`).

Pure functions over what the flight recorded (the mission report, quad-control's /api/state at the
end, the processes' logs), so the verdict is unit-tested without flying. Each target gives one
`Check`: its name, the measured figure, the limit, and - on a miss - why, in words.

Targets:
  hold          max error of the true camera position while holding (after settling) <= 0.15 m
  waypoint i    position error at each waypoint (last second after settling) <= 0.15 m
  touchdown     hardest ground contact (vertical speed) <= 0.5 m/s
  SLAM ATE      RMSE of quad-control's SLAM trajectory against the emulator's truth <= 30 mm
  SLAM resets   0 new SLAM maps (new world frames) after the first, *observed*: the largest count
                among slam-server's log ("map <id> started (new"), quad-control's log ("SLAM link:
                connected to ...: map <id> started (new" / the older "(a new SLAM session)") and
                quad-control's /api/state (slam.sessions_started). Not observable -> a miss.
  rig real-time the rig kept real time, so a miss above is the system's and not an overloaded
                emulator's: the Kinect emulator delivered >= 90 % of the frames the camera pump
                requested (a frame still rendering when the next is due is superseded), and the
                simulation ran at >= 0.95 of wall-clock speed (LiveRig.realtime_factor).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

HOLD_MAX_M = 0.15
WAYPOINT_MAX_M = 0.15
TOUCHDOWN_MAX_MPS = 0.5
ATE_MAX_M = 0.030
MAX_MAP_RESETS = 0
# Rig health: the camera pump asks for a frame every 1/fps; below 90 % delivered the SLAM sees a
# different (slower) camera than the flight was designed for.
MIN_DELIVERED_RATIO = 0.90
# LiveRig drops lag beyond one RC frame; a factor below 0.95 means the simulated craft ran >5 %
# slower than the wall clock the ground station lives in.
MIN_REALTIME_FACTOR = 0.95


@dataclass(frozen=True)
class Check:
    target: str
    passed: bool
    measured: str
    limit: str
    why: str = ""

    def line(self) -> str:
        head = (
            f"{'PASS' if self.passed else 'MISS'} {self.target}: {self.measured} "
            f"(target {self.limit})"
        )
        return head if self.passed else f"{head} - {self.why}"


def _fmt(v, unit: str, scale: float = 1.0, digits: int = 3) -> str:
    return "n/a" if v is None else f"{v * scale:.{digits}f} {unit}"


def map_resets(
    slam_server_log: str | None, quad_control_log: str | None, state: dict | None
) -> dict:
    """New SLAM maps after the first, from every source that is available."""
    sources: dict[str, int] = {}
    if slam_server_log is not None:
        n = len(re.findall(r"\bmap [0-9a-f]+ started \(new", slam_server_log))
        # Before maps outlived connections, each connection was a new map.
        n_old = len(re.findall(r"slam-server: client connected", slam_server_log))
        sources["slam-server log"] = max(n, n_old) - 1 if max(n, n_old) > 0 else 0
    if quad_control_log is not None:
        n = len(
            re.findall(r"SLAM link: connected to .*: map [0-9a-f]+ started \(new", quad_control_log)
        )
        n_old = len(re.findall(r"reconnecting \(a new SLAM session\)", quad_control_log))
        sources["quad-control log"] = max(n - 1, 0) + n_old
    slam_state = (state or {}).get("slam") or {}
    if "sessions_started" in slam_state:
        sources["quad-control /api/state"] = max(int(slam_state["sessions_started"]) - 1, 0)
    disconnects = len(re.findall(r"SLAM link: disconnected: ", quad_control_log or ""))
    causes = re.findall(r"SLAM link: disconnected: (.*?); reconnecting", quad_control_log or "")
    server_closes = re.findall(r"client #\d+ \(.*?\) closed: (.*?);", slam_server_log or "")
    resumes = len(re.findall(r"\bmap [0-9a-f]+ resumed", slam_server_log or ""))
    return {
        "resets": max(sources.values()) if sources else None,
        "sources": sources,
        "link_breaks": disconnects,
        "resumes": resumes,
        "disconnect_causes": causes[:5],
        "server_close_causes": server_closes[:5],
    }


def rig_health(report: dict, fps: float) -> dict:
    kinect = (report.get("stream") or {}).get("kinect") or {}
    submitted = kinect.get("submitted")
    delivered = kinect.get("delivered")
    ratio = delivered / submitted if submitted else None
    return {
        "requested_fps": fps,
        "frames_requested": submitted,
        "frames_delivered": delivered,
        "frames_superseded": kinect.get("superseded"),
        "delivered_ratio": None if ratio is None else round(ratio, 3),
        "render_ms_median": kinect.get("render_ms_median"),
        "realtime_factor": report.get("realtime_factor"),
        "received_fps": (report.get("stream") or {}).get("received_fps"),
    }


def _rig_check(report: dict, fps: float) -> Check:
    rig = rig_health(report, fps)
    ratio, rtf = rig["delivered_ratio"], rig["realtime_factor"]
    rig_ok = (
        ratio is not None
        and rtf is not None
        and ratio >= MIN_DELIVERED_RATIO
        and rtf >= MIN_REALTIME_FACTOR
    )
    if rig_ok:
        why = ""
    elif ratio is None or rtf is None:
        why = "the rig did not report its delivered frames / real-time factor"
    else:
        why = (
            f"rig overloaded: {rig['frames_delivered']} of {rig['frames_requested']} "
            "camera frames delivered "
            f"({rig['frames_superseded']} superseded, render median {rig['render_ms_median']} ms), "
            f"simulation at {rtf:.2f}x wall clock: "
            "the machine could not run the emulators in real time, "
            "so other misses may be the rig's, not the system's"
        )
    return Check(
        "rig real-time",
        rig_ok,
        f"{_fmt(ratio, '', 100, 0).strip()}% frames delivered, "
        f"{rtf if rtf is not None else 'n/a'}x real time",
        f">= {MIN_DELIVERED_RATIO:.0%} delivered, >= {MIN_REALTIME_FACTOR}x",
        why,
    )


def _aborted_checks(report: dict, plan: str) -> list[Check]:
    aborted = report.get("aborted")
    if not aborted:
        return []
    return [
        Check("flight completed", False, "aborted", plan, f"the mission stopped: {aborted[:300]}")
    ]


def _hold_check(report: dict) -> Check:
    h = report.get("hold") or {}
    hv = h.get("max_m")
    return Check(
        "hold",
        hv is not None and hv <= HOLD_MAX_M,
        _fmt(hv, "m"),
        f"<= {HOLD_MAX_M} m",
        "not measured (the mission stopped before the hold was scored)"
        if hv is None
        else f"the craft was {hv:.3f} m from its hold point "
        f"(horizontal {h.get('max_horizontal_m')} m, "
        f"vertical {h.get('max_vertical_m')} m)",
    )


def _ate_check(report: dict) -> Check:
    ate = report.get("ate") or {}
    av = ate.get("ate_rmse_m")
    return Check(
        "SLAM ATE",
        av is not None and av <= ATE_MAX_M,
        _fmt(av, "mm", 1000, 1),
        f"<= {ATE_MAX_M * 1000:.0f} mm",
        f"ATE not available: {ate.get('error', ate)}"
        if av is None
        else f"SLAM trajectory {av * 1000:.1f} mm RMSE from the truth "
        f"(max {ate.get('ate_max_m', 0) * 1000:.0f} mm)",
    )


def _resets_check(resets: dict) -> Check:
    r = resets.get("resets")
    return Check(
        "SLAM map resets",
        r is not None and r <= MAX_MAP_RESETS,
        "not observed"
        if r is None
        else f"{r} (link breaks {resets.get('link_breaks', 0)}, "
        f"resumed {resets.get('resumes', 0)})",
        f"{MAX_MAP_RESETS}",
        "no log or state to count them from"
        if r is None
        else f"{r} new map(s) after the first (sources {resets.get('sources')}; causes: "
        f"{resets.get('disconnect_causes') or resets.get('server_close_causes')})",
    )


def judge(report: dict, resets: dict, fps: float) -> list[Check]:
    """One Check per target of `make demo` (scenario 2), in a fixed order."""
    checks = [
        _rig_check(report, fps),
        *_aborted_checks(report, "take-off, hold, 2 waypoints, landing"),
        _hold_check(report),
    ]
    wps = report.get("waypoints") or []
    for i in range(max(2, len(wps))):
        w = wps[i] if i < len(wps) else {}
        v = w.get("max_m")
        checks.append(
            Check(
                f"waypoint {i + 1}",
                v is not None and v <= WAYPOINT_MAX_M,
                _fmt(v, "m"),
                f"<= {WAYPOINT_MAX_M} m",
                "not reached" if v is None else f"ended {v:.3f} m from the waypoint",
            )
        )
    td = (report.get("landing") or {}).get("touchdown_vertical_speed_mps")
    if td is None and report.get("touchdowns_mps"):  # an aborted flight that still came down
        td = max(report["touchdowns_mps"])
    checks.append(
        Check(
            "touchdown",
            td is not None and td <= TOUCHDOWN_MAX_MPS,
            _fmt(td, "m/s", digits=2),
            f"<= {TOUCHDOWN_MAX_MPS} m/s",
            "no landing recorded" if td is None else f"hit the floor at {td:.2f} m/s",
        )
    )
    checks += [_ate_check(report), _resets_check(resets)]
    return checks


def judge_hold(report: dict, resets: dict, fps: float) -> list[Check]:
    """The targets of a hold-only flight (the load scenario): rig real-time, hold, SLAM ATE,
    resets."""
    return [
        _rig_check(report, fps),
        *_aborted_checks(report, "take-off and hold"),
        _hold_check(report),
        _ate_check(report),
        _resets_check(resets),
    ]
