"""A soak mission's outcome from the emulator's truth (pure; the rules of docs/hil.md, Soak).

completed                        every step happened, down and disarmed, no radio failsafe before
                                 the land command
landed by failsafe as expected   the APM's radio failsafe engaged when a fault took the control
                                 link away (after a ground-station kill, or during a control-link
                                 loss window, up to FAILSAFE_AFTER_LOSS_S after it), or when a fault
                                 took the poses away for longer than quad-control's lost-hold
                                 (a stream stall of STALL_CAN_OUTLAST_S or more, a slam-server
                                 kill): quad-control's designed blind landing withholds commands
                                 and the firmware failsafe lands (docs/control.md, state machine);
                                 and the craft is down and disarmed. How far the blind landing
                                 drifted is in the reason when it passed the fly-away radius: the
                                 APM's LAND has no position source on this craft, so its drift is
                                 the velocity it had and the air's, not a decision of the software
                                 (docs/failsafe.md, "Blind landings")
aborted (landed safely)          not completed and not explained so, but down and disarmed within
                                 the fly-away radius with a soft touchdown: a finding
lost                             not down and disarmed; or a touchdown harder than the limit; or,
                                 while the craft still flew on quad-control's commands (before any
                                 radio failsafe), beyond the fly-away radius of every point the
                                 mission sent it to (max_distance_under_control_m: the hold
                                 point and the waypoints clicked so far); or beyond it after a
                                 radio failsafe that no injected fault explains
"""

from __future__ import annotations

import re

# Within 2 m of where the mission meant to be: the APM's LAND has no position source and drifts
# 0.6-1.5 m in the gusts (hil/scenarios/test_scenario_slam_closed_loop.py FLYAWAY_RADIUS_M).
FLYAWAY_RADIUS_M = 2.0
# The scenarios' 0.5 m/s touchdown limit, +0.01 for the airframe model's 2.5 ms step.
TOUCHDOWN_LIMIT_MPS = 0.51
# A control-link loss explains a radio failsafe that engages up to this long after its window: the
# firmware fails safe 250 ms after the last command it applied, the APM 3 RC frames (60 ms) after
# that; a stall of 200 ms begun at the window's end can still be delivering.
FAILSAFE_AFTER_LOSS_S = 1.0

# quad-control's lost-hold lasts 2000 ms before the blind landing (controller.lost_hold_ms); a pose
# outage explains a failsafe that engages until this long after the outage's end: the lost-hold,
# the SLAM link's reconnect (every 100 ms) after a slam-server restart, relocalisation.
LOST_HOLD_S = 2.0
POSE_OUTAGE_MARGIN_S = LOST_HOLD_S + 3.0
# A stall this long, with the frames the receiver and SLAM then take to catch up, can outlast the
# 2 s lost-hold. A shorter one outlasts it only when SLAM then stays lost or relocalises to a pose
# the jump gate refuses: that blind landing is SLAM's failure to recover, not the stall's doing,
# and stays unexplained (docs/failsafe.md, Known limits).
STALL_CAN_OUTLAST_S = 1.0
POSE_OUTAGE_KINDS = ("stream_stall", "slam_server_kill")

_EVENT = re.compile(r"^\s*([0-9.]+) s (.*)$")


def failsafe_times_s(events: list[str]) -> list[float]:
    """Simulated times (s) of radio failsafes engaging, from the report's "T s text" event lines."""
    out = []
    for line in events:
        m = _EVENT.match(line)
        if m and "failsafe" in m.group(2) and "cleared" not in m.group(2):
            out.append(float(m.group(1)))
    return out


def judge(
    truth: dict,
    completed_steps: bool,
    faults: list[dict],
    takeoff_sim_s: float | None,
    land_sim_s: float | None,
    gave_up: str = "",
) -> tuple[str, str]:
    """(outcome, reason). truth: armed_at_end, landed_at_end, failsafe_events ("T s text"),
    touchdowns_mps, max_distance_from_path_m; faults: the injected faults (kind, sim_s,
    duration_s); takeoff_sim_s / land_sim_s: when the take-off / land command was given (None:
    never). A failsafe before the take-off (the previous ground station stopping) does not count."""
    down = not truth["armed_at_end"] and truth["landed_at_end"]
    far = truth["max_distance_from_path_m"]
    # Older reports have no split: the whole mission counts as flown under control.
    far_control = truth.get("max_distance_under_control_m", far)
    touchdowns = truth["touchdowns_mps"]
    hard = bool(touchdowns) and max(touchdowns) > TOUCHDOWN_LIMIT_MPS
    if not down or far_control > FLYAWAY_RADIUS_M or hard:
        why = []
        if not down:
            why.append("not down and disarmed")
        if far_control > FLYAWAY_RADIUS_M:
            why.append(f"{far_control:.2f} m from its path under control")
        if hard:
            why.append(f"touchdown {max(touchdowns):.2f} m/s")
        return "lost", "; ".join(why)
    blind = (
        f"; the blind landing drifted {far:.2f} m from its path" if far > FLYAWAY_RADIUS_M else ""
    )
    early = [
        t
        for t in failsafe_times_s(truth["failsafe_events"])
        if (takeoff_sim_s is not None and t >= takeoff_sim_s)
        and (land_sim_s is None or t < land_sim_s)
    ]
    if early:
        first = early[0]
        for f in faults:
            if f["kind"] == "ground_station_kill" and f["sim_s"] <= first:
                return "landed by failsafe as expected", "ground station killed" + blind
            if (
                f["kind"] == "control_loss"
                and f["sim_s"] <= first <= f["sim_s"] + f["duration_s"] + FAILSAFE_AFTER_LOSS_S
            ):
                return "landed by failsafe as expected", "control-link loss" + blind
        for f in faults:
            if (
                f["kind"] in POSE_OUTAGE_KINDS
                and (f["kind"] != "stream_stall" or f["duration_s"] >= STALL_CAN_OUTLAST_S)
                and f["sim_s"] <= first <= f["sim_s"] + f["duration_s"] + POSE_OUTAGE_MARGIN_S
            ):
                return (
                    "landed by failsafe as expected",
                    f"blind landing after a pose outage ({f['kind']} {f['duration_s']:.1f} s)"
                    + blind,
                )
        if far > FLYAWAY_RADIUS_M:
            return "lost", f"{far:.2f} m from its path after a radio failsafe no fault explains"
        return (
            "aborted (landed safely)",
            f"radio failsafe at {first:.1f} s without a fault to explain it",
        )
    if completed_steps:
        return "completed", "all steps"
    return "aborted (landed safely)", gave_up[:200]
