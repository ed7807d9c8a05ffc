"""Operator scripts for closed-loop flights (hilrig.slam_flight): what a user does on the dashboard,
step by step, with the figures each step is scored by. Shared by the scenario tests and `make demo`.

Every wait has a deadline; a step that does not happen raises TimeoutError naming it and the last
state quad-control reported. Times in reports are seconds of the rig's simulated clock.
"""

from __future__ import annotations

import time

import numpy as np

from hilrig.slam_flight import SlamFlight, camera_room_position, goal_in_room, hold_error

HOLD_HEIGHT_M = 1.7  # thesis: hold height after take-off (quad-control's controller.hold_height_m)
SETTLE_S = 5.0  # after quad-control reports "hold": the PID settles before the hold is scored
ARRIVAL_SETTLE_S = 6.0  # after arriving at a waypoint: settle, then score the last second
TURN_DONE_DEG = 5.0  # a turn is done when quad-control's heading is this close to the setpoint's
SETPOINT_MATCH_M = (
    0.01  # the hold setpoint equals the clicked waypoint (JSON round trip of doubles)
)


def _say(progress, text: str) -> None:
    if progress is not None:
        progress(text)


def take_off(flight: SlamFlight, progress=None) -> dict:
    """Waits for tracking and the floor, arms (ArduCopter's stick gesture through the real
    firmware), takes off to the hold height. Returns the start position (room frame) and times."""
    _say(progress, "waiting for SLAM tracking and the floor plane")
    flight.wait_until(
        lambda s: s.get("tracking") and (s["floor"]["found"] or s["floor"]["fallback"]),
        timeout_s=90,
        what="tracking + floor",
    )
    start = camera_room_position(flight.rig.snapshot(), flight.options.mount)
    _say(progress, "arm (stick gesture)")
    flight.command("arm")
    # quad-control holds the gesture (throttle 0, yaw right) for controller.arm_gesture_ms, then
    # centres yaw: take-off is accepted from then on.
    flight.wait_until(
        lambda s: s["state"] == "armed"
        and s["command"]["yaw_pct"] == 0.0
        and flight.rig.snapshot().armed,
        timeout_s=20,
        what="armed (gesture finished)",
    )
    _say(progress, f"take off to {HOLD_HEIGHT_M} m")
    t_takeoff = flight.rig.sim_us
    # Refused while no pose is fresh (e.g. a stalled stream): an operator clicks again.
    end = time.monotonic() + 20.0
    while True:
        try:
            flight.command("takeoff")
            break
        except RuntimeError as e:
            if "no tracked pose" not in str(e) or time.monotonic() > end:
                raise
            time.sleep(0.2)
    flight.wait_until(lambda s: s["state"] == "hold", timeout_s=60, what="take-off -> hold")
    return {
        "start_room_m": start,
        "takeoff_sim_s": t_takeoff / 1e6,
        "hold_reached_sim_s": flight.rig.sim_us / 1e6,
    }


def hold(flight: SlamFlight, start_room: np.ndarray, seconds: float, progress=None) -> dict:
    """Holds where take-off left the craft; scores the true camera position after SETTLE_S."""
    goal = goal_in_room(start_room, (0.0, 0.0, HOLD_HEIGHT_M))
    _say(progress, f"hold {seconds:.0f} s")
    flight.hold_for(SETTLE_S)
    t0 = flight.rig.sim_us
    flight.hold_for(seconds)
    return hold_error(flight.rig.history(), goal, flight.options.mount, t0, flight.rig.sim_us)


def go_to(
    flight: SlamFlight, start_room: np.ndarray, x_m: float, y_m: float, progress=None
) -> dict:
    """Clicks a waypoint (floor frame); waits for arrival (quad-control back in hold), settles, and
    scores the true position against the waypoint."""
    _say(progress, f"waypoint ({x_m:.1f}, {y_m:.1f}) m")
    flight.waypoint(x_m, y_m)
    flight.wait_until(lambda s: s["state"] == "go-to-waypoint", timeout_s=5, what="go-to-waypoint")
    t_start = flight.rig.sim_us
    # Arrived: holding with the setpoint on the waypoint (quad-control holds where it arrived). Not
    # the "waypoint reached" event alone: a tracking blip right after the arrival replaces it with
    # "tracking back" before the next poll (seen under load: the craft held at the waypoint while
    # the
    # operator waited 60 s for the event).
    flight.wait_until(
        lambda s: s["state"] == "hold"
        and ("waypoint reached" in s["last_event"] or _setpoint_at(s, x_m, y_m)),
        timeout_s=60,
        what=f"arrival at ({x_m}, {y_m})",
    )
    t_arrived = flight.rig.sim_us
    flight.hold_for(ARRIVAL_SETTLE_S)
    goal = goal_in_room(start_room, (x_m, y_m, HOLD_HEIGHT_M))
    t_end = flight.rig.sim_us
    err = hold_error(flight.rig.history(), goal, flight.options.mount, t_end - 1e6, t_end)
    return {"leg_s": round((t_arrived - t_start) / 1e6, 1), **err}


def _heading_error_deg(state: dict) -> float:
    """quad-control's heading (SLAM) against its setpoint's, wrapped to [-180, 180)."""
    pose, sp = state.get("pose"), state.get("setpoint") or {}
    if not pose or "yaw_deg" not in sp:
        return 1e9
    return (pose["yaw_deg"] - sp["yaw_deg"] + 180.0) % 360.0 - 180.0


def turn(
    flight: SlamFlight, start_room: np.ndarray, yaw_ccw_deg: float, hold_s: float, progress=None
) -> dict:
    """Turns in place by `yaw_ccw_deg` (the dashboard's manual step), waits until quad-control's
    heading is within TURN_DONE_DEG of the new setpoint, then holds `hold_s` (scored after
    SETTLE_S). Scores the true camera position during the turn and the hold against the take-off
    hold point, and the true heading change."""
    goal = goal_in_room(start_room, (0.0, 0.0, HOLD_HEIGHT_M))
    _say(progress, f"turn {yaw_ccw_deg:+.0f} deg")
    yaw0 = flight.rig.snapshot().yaw_rad
    t0 = flight.rig.sim_us
    flight.manual(yaw_ccw_deg=yaw_ccw_deg)
    flight.wait_until(
        lambda s: s["state"] == "hold" and abs(_heading_error_deg(s)) <= TURN_DONE_DEG,
        timeout_s=60,
        what=f"turn {yaw_ccw_deg:+.0f} deg",
    )
    t_turned = flight.rig.sim_us
    # NED yaw grows clockwise seen from above: a counter-clockwise turn decreases it.
    turned_deg = -float(
        np.degrees((flight.rig.snapshot().yaw_rad - yaw0 + np.pi) % (2 * np.pi) - np.pi)
    )
    return {
        "yaw_ccw_deg": yaw_ccw_deg,
        "true_turn_deg": round(turned_deg, 1),
        "turn_s": round((t_turned - t0) / 1e6, 2),
        "during_turn": hold_error(flight.rig.history(), goal, flight.options.mount, t0, t_turned),
        "hold": hold(flight, start_room, hold_s, progress),
    }


def _setpoint_at(state: dict, x_m: float, y_m: float) -> bool:
    """quad-control's setpoint is on (x_m, y_m) (floor frame; it is set to the waypoint on
    arrival)."""
    sp = state.get("setpoint") or {}
    return (
        abs(sp.get("x_m", 1e9) - x_m) <= SETPOINT_MATCH_M
        and abs(sp.get("y_m", 1e9) - y_m) <= SETPOINT_MATCH_M
    )


def land(flight: SlamFlight, progress=None) -> dict:
    """Lands with quad-control's own landing (throttle ramp) and waits for the disarm. A craft that
    quad-control is already landing (blind: tracking did not come back within lost_hold_ms) or that
    is on the ground is only waited for; `landed_by` says which."""
    t_land = flight.rig.sim_us
    state = flight.state().get("state")
    if state in ("land", "disarmed"):
        _say(progress, f"land: quad-control is already in {state}")
        landed_by = f"quad-control ({state} before the operator asked)"
    else:
        _say(progress, "land")
        flight.command("land")
        landed_by = "operator"
    flight.wait_until(
        lambda s: s["state"] == "disarmed" and not flight.rig.snapshot().armed,
        timeout_s=90,
        what="landed and disarmed",
    )
    touchdowns = [round(v, 3) for v in flight.rig.fc.touchdowns_mps]
    # Near the floor the Kinect sees little (nothing closer than 0.5 m): if SLAM loses track,
    # quad-control hands the landing to the craft's failsafe (APM LAND), which is by design.
    handed_over = [e for t, e in flight.rig.fc.events if t >= t_land and "failsafe" in e]
    return {
        "t_land_sim_s": t_land / 1e6,
        "landed_by": landed_by,
        "handed_over_to_failsafe": bool(handed_over),
        # The hardest ground contact of the flight (a take-off hop or a bounce counts too).
        "touchdown_vertical_speed_mps": max(touchdowns) if touchdowns else None,
        "touchdowns_mps": touchdowns,
        "touchdowns": len(touchdowns),
    }


def scenario2(
    flight: SlamFlight, waypoints=((1.0, 0.0), (1.0, 0.8)), hold_s: float = 10.0, progress=None
) -> dict:
    """Take off, hold, fly to two waypoints (floor frame, m), land. The figures of the flight."""
    t0 = time.monotonic()
    to = take_off(flight, progress)
    start = to["start_room_m"]
    report: dict = {"hold": hold(flight, start, hold_s, progress)}
    report["waypoints"] = [go_to(flight, start, x, y, progress) for x, y in waypoints]
    report["landing"] = land(flight, progress)
    flight.hold_for(1.0)
    report["final_distance_to_last_waypoint_m"] = round(
        float(
            np.hypot(
                *(
                    camera_room_position(flight.rig.snapshot(), flight.options.mount)[:2]
                    - goal_in_room(start, (*waypoints[-1], 0.0))[:2]
                )
            )
        ),
        3,
    )
    t_land_us = report["landing"]["t_land_sim_s"] * 1e6
    report["failsafe_events"] = [
        e for t, e in flight.rig.fc.events if t < t_land_us and "failsafe" in e
    ]
    report["rejected_pose_jumps"] = flight.state().get("rejected_poses")
    report["wall_s"] = round(time.monotonic() - t0, 1)
    report["realtime_factor"] = round(flight.rig.realtime_factor, 3)
    return report
