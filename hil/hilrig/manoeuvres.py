"""Fast manoeuvres for closed-loop flights (hilrig.slam_flight): 60 deg/s turns and 1 m/s dashes
flown through quad-control's dashboard API (POST /api/manoeuvre: a timed move / turn of the hold
setpoint with its rate fed forward, FlightController::manoeuvre), with holds between, scored on the
emulator's truth.

The operator asks for each manoeuvre the way a mission planner would; quad-control bounds the rates
(controller.max_manoeuvre_speed_m_per_s, max_manoeuvre_yaw_rate_deg_per_s) and the flight envelope
bounds where it may go. Every wait has a deadline; a step that does not happen raises TimeoutError
naming it. A manoeuvre quad-control refuses (it accepts one only in hold: after a loss of tracking
the craft may be in lost-hold or landing blind) ends the sequence and is reported with the state
and last event that explain it; the craft is then landed and the report completed, so a refusal is
a scored miss, not a lost flight record. Times in reports are seconds of the rig's simulated clock.
"""

from __future__ import annotations

import json
import math
import time
import urllib.error
import urllib.request

import numpy as np

from hilrig import missions
from hilrig.slam_flight import SlamFlight, camera_room_position, goal_in_room, hold_error

YAW_RATE_DEG_S = 60.0  # the turn rate asked: the camera bench's fast turn (hil/tools/render_tum.py)
DASH_SPEED_M_S = 1.0  # the dash speed asked: the camera bench's dash
DASH_M = 2.0  # out 2 m along the heading, then back: stays 1.5 m off the room's +x wall
# +180 and back (the view swings through the whole room and returns), a quarter turn to end facing
# another wall for the landing.
TURNS_CCW_DEG = (180.0, -180.0)
LAST_TURN_CCW_DEG = 90.0
# After a manoeuvre's setpoint has arrived, the hold is scored only after this long: the setpoint's
# speed ramps down to zero at the end of the profile (controller.manoeuvre_accel_mss), so what is
# left is the tracking error the position loop closes with its ~0.6 s time constant
# (1 / (damping x natural frequency) of the cascade's 1/s, 3.5/s: docs/control.md); 2 s is three
# and a half of them, leaving ~3 % of the error at arrival. The error during these 2 s is reported
# too ("settling").
MANOEUVRE_SETTLE_S = 2.0
MANOEUVRE_HOLD_S = 6.0  # the scored hold after each manoeuvre
# A manoeuvre's profile lasts at most 2 x ramp + distance / rate (a 180 deg turn at 60 deg/s: 3.5
# s); quad-control reports it done when the setpoint arrives. 30 s also covers a rig that runs
# slower than real time.
MANOEUVRE_TIMEOUT_S = 30.0


class ManoeuvreRefused(RuntimeError):
    """quad-control answered a manoeuvre request with an error (its reason is the message)."""


def post_manoeuvre(
    flight: SlamFlight,
    *,
    forward_m: float = 0.0,
    left_m: float = 0.0,
    yaw_ccw_deg: float = 0.0,
    speed_m_per_s: float = 0.0,
    yaw_rate_deg_per_s: float = 0.0,
) -> dict:
    """POST /api/manoeuvre on quad-control's dashboard; raises ManoeuvreRefused with its reason when
    refused."""
    body = {
        "forward_m": forward_m,
        "left_m": left_m,
        "yaw_ccw_deg": yaw_ccw_deg,
        "speed_m_per_s": speed_m_per_s,
        "yaw_rate_deg_per_s": yaw_rate_deg_per_s,
    }
    req = urllib.request.Request(
        f"http://127.0.0.1:{flight.dashboard_port}/api/manoeuvre",
        data=json.dumps(body).encode(),
        method="POST",
        headers={"Content-Type": "application/json"},
    )
    try:
        with urllib.request.urlopen(req, timeout=5.0) as r:
            status, reply = r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        status, reply = e.code, json.loads(e.read() or b"null")
    flight.operator_events.append((time.monotonic(), f"manoeuvre {json.dumps(body)}", str(reply)))
    if status != 200:
        raise ManoeuvreRefused(f"manoeuvre refused ({status}): {reply}")
    return reply


def _true_turn_deg(yaw0_rad: float, yaw1_rad: float) -> float:
    """The true heading change, counter-clockwise seen from above (NED yaw grows clockwise), wrapped
    to [-180, 180); a 180 deg turn may read as -180."""
    return -math.degrees((yaw1_rad - yaw0_rad + math.pi) % (2 * math.pi) - math.pi)


def cross_track(history, a_room: np.ndarray, b_room: np.ndarray, mount, from_us, to_us) -> dict:
    """The camera's true horizontal distance from the segment a -> b (room frame) and its height
    error against b over [from_us, to_us]: how far a move strays from its straight line."""
    sel = [s for s in history if from_us <= s.t_us <= to_us]
    if not sel:
        return {"samples": 0}
    pos = np.array([camera_room_position(s, mount) for s in sel])
    ab = b_room[:2] - a_room[:2]
    length2 = float(ab @ ab)
    along = np.clip(((pos[:, :2] - a_room[:2]) @ ab) / length2, 0.0, 1.0) if length2 else 0.0
    nearest = a_room[:2] + np.outer(along, ab) if length2 else a_room[:2]
    off = np.linalg.norm(pos[:, :2] - nearest, axis=1)
    return {
        "max_cross_track_m": round(float(off.max()), 3),
        "max_vertical_m": round(float(np.abs(pos[:, 2] - b_room[2]).max()), 3),
        "samples": len(sel),
    }


def fly_manoeuvre(
    flight: SlamFlight,
    start_room: np.ndarray,
    from_floor_xy: tuple[float, float],
    goal_floor_xy: tuple[float, float],
    request: dict,
    progress=None,
) -> dict:
    """Asks for one manoeuvre, waits for quad-control to report it done, then scores: the true
    heading change, how far the truth strayed from the straight line between the holds during the
    manoeuvre (for a turn: from the hold point), the truth against the goal during
    MANOEUVRE_SETTLE_S and over the MANOEUVRE_HOLD_S hold after it. `from_floor_xy` /
    `goal_floor_xy`: the hold setpoint before and after (quad-control's floor frame)."""
    goal = goal_in_room(start_room, (*goal_floor_xy, missions.HOLD_HEIGHT_M))
    origin = goal_in_room(start_room, (*from_floor_xy, missions.HOLD_HEIGHT_M))
    if progress is not None:
        progress(f"manoeuvre {request}")
    yaw0 = flight.rig.snapshot().yaw_rad
    t0 = flight.rig.sim_us
    post_manoeuvre(flight, **request)
    st = flight.wait_until(
        lambda s: not s.get("manoeuvre_active") or s["state"] != "hold",
        timeout_s=MANOEUVRE_TIMEOUT_S,
        what=f"manoeuvre {request} done",
    )
    t_done = flight.rig.sim_us
    flight.hold_for(MANOEUVRE_SETTLE_S)
    t_settled = flight.rig.sim_us
    yaw1 = flight.rig.snapshot().yaw_rad
    flight.hold_for(MANOEUVRE_HOLD_S)
    t_end = flight.rig.sim_us
    history = flight.rig.history()
    mount = flight.options.mount
    return {
        "request": request,
        "state_after": st["state"],
        "manoeuvre_s": round((t_done - t0) / 1e6, 2),
        "true_turn_deg": round(_true_turn_deg(yaw0, yaw1), 1),
        "during": cross_track(history, origin, goal, mount, t0, t_done),
        "settling": hold_error(history, goal, mount, t_done, t_settled),
        "hold": hold_error(history, goal, mount, t_settled, t_end),
    }


def fast_manoeuvres(flight: SlamFlight, progress=None) -> dict:
    """Take off, hold, turn +180 / -180 deg at 60 deg/s, dash 2 m forward and back at 1 m/s, turn
    +90 deg, hold after each, land. The figures of the flight (truth, SLAM, failsafe)."""
    wall0 = time.monotonic()
    to = missions.take_off(flight, progress)
    start = to["start_room_m"]
    report: dict = {"hold": missions.hold(flight, start, 5.0, progress)}
    turn = {"yaw_rate_deg_per_s": YAW_RATE_DEG_S}
    home, out = (0.0, 0.0), (DASH_M, 0.0)
    dash = {"speed_m_per_s": DASH_SPEED_M_S}
    # (from, to, request) in quad-control's floor frame. After the two turns the craft faces the
    # take-off heading again (floor +x): forward is floor +x; back is flown backwards.
    plan = [(home, home, {"yaw_ccw_deg": yaw, **turn}) for yaw in TURNS_CCW_DEG]
    plan += [
        (home, out, {"forward_m": DASH_M, **dash}),
        (out, home, {"forward_m": -DASH_M, **dash}),
        (home, home, {"yaw_ccw_deg": LAST_TURN_CCW_DEG, **turn}),
    ]
    steps = []
    report["refused"] = None
    for origin, goal, request in plan:
        try:
            steps.append(fly_manoeuvre(flight, start, origin, goal, request, progress))
        except ManoeuvreRefused as e:
            st = flight.state()
            report["refused"] = {
                "request": request,
                "reason": str(e),
                "state": st.get("state"),
                "last_event": st.get("last_event"),
            }
            if progress is not None:
                progress(f"refused: {report['refused']}")
            break
    report["manoeuvres"] = steps
    report["manoeuvres_planned"] = len(plan)
    report["landing"] = missions.land(flight, progress)
    t_land_us = report["landing"]["t_land_sim_s"] * 1e6
    report["failsafe_events"] = [
        e for t, e in flight.rig.fc.events if t < t_land_us and "failsafe" in e
    ]
    st = flight.state()
    report["rejected_pose_jumps"] = st.get("rejected_poses")
    report["manoeuvres_done"] = st.get("manoeuvres_done")
    report["final_position_room_m"] = [
        round(float(v), 3)
        for v in camera_room_position(flight.rig.snapshot(), flight.options.mount)
    ]
    report["wall_s"] = round(time.monotonic() - wall0, 1)
    report["realtime_factor"] = round(flight.rig.realtime_factor, 3)
    return report


def targets_missed(report: dict, ate_limit_m: float, hold_limit_m: float) -> list[str]:
    """The targets a fast_manoeuvres() flight (with SlamFlight.scores()) missed, each with the
    figure that missed it: a failsafe, SLAM ATE over `ate_limit_m`, a hold over `hold_limit_m`, a
    refused manoeuvre, fewer manoeuvres flown than planned."""
    misses = []
    if report["failsafe_events"]:
        misses.append(f"failsafe: {report['failsafe_events']}")
    ate = report["ate"].get("ate_rmse_m")
    if ate is None or ate > ate_limit_m:
        misses.append(f"SLAM ATE {ate} m (limit {ate_limit_m}; {report['ate']})")
    for m in report["manoeuvres"]:
        if m["hold"].get("max_m", math.inf) > hold_limit_m:
            misses.append(f"hold after {m['request']}: {m['hold']} (limit {hold_limit_m} m)")
    refused = report.get("refused")
    if refused:
        misses.append(
            f"manoeuvre {refused['request']} refused: {refused['reason']} (quad-control in "
            f"{refused['state']}: {refused['last_event']})"
        )
    flown, planned = len(report["manoeuvres"]), report["manoeuvres_planned"]
    if flown < planned:
        misses.append(f"{flown} of {planned} manoeuvres flown")
    return misses
