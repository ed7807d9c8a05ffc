"""The soak's outcome rules (soak.outcome.judge), table-driven: truth and the faults injected."""

from __future__ import annotations

import pytest
from soak.outcome import judge

DOWN = {
    "armed_at_end": False,
    "landed_at_end": True,
    "failsafe_events": [],
    "touchdowns_mps": [0.3],
    "max_distance_from_path_m": 0.4,
}


def truth(**kw) -> dict:
    return {**DOWN, **kw}


def fault(kind: str, sim_s: float, duration_s: float = 0.0) -> dict:
    return {"kind": kind, "sim_s": sim_s, "duration_s": duration_s}


TAKEOFF, LAND = 100.0, 200.0
CASES = [
    # (name, truth, completed, faults, land, expected outcome, reason contains)
    ("all steps, down", truth(), True, [], LAND, "completed", "all steps"),
    (
        "failsafe before take-off ignored",
        truth(failsafe_events=["90.0 s radio failsafe: x"]),
        True,
        [],
        LAND,
        "completed",
        "",
    ),
    (
        "failsafe during landing ignored",
        truth(failsafe_events=["201.0 s radio failsafe: x"]),
        True,
        [],
        LAND,
        "completed",
        "",
    ),
    (
        "cleared event is not a failsafe",
        truth(failsafe_events=["150.0 s radio failsafe cleared"]),
        True,
        [],
        LAND,
        "completed",
        "",
    ),
    (
        "kill then failsafe",
        truth(failsafe_events=["150.3 s radio failsafe: throttle 950 us"]),
        False,
        [fault("ground_station_kill", 150.0)],
        None,
        "landed by failsafe as expected",
        "ground station killed",
    ),
    (
        "failsafe inside a control-loss window",
        truth(failsafe_events=["153.0 s radio failsafe: x"]),
        False,
        [fault("control_loss", 150.0, 4.0)],
        None,
        "landed by failsafe as expected",
        "control-link loss",
    ),
    (
        "failsafe long after a control-loss window",
        truth(failsafe_events=["170.0 s radio failsafe"]),
        False,
        [fault("control_loss", 150.0, 4.0)],
        None,
        "aborted (landed safely)",
        "without",
    ),
    (
        "blind landing after a long stall",
        truth(failsafe_events=["153.5 s radio failsafe: x"]),
        False,
        [fault("stream_stall", 150.0, 2.5)],
        None,
        "landed by failsafe as expected",
        "pose outage",
    ),
    (
        "a short stall explains nothing",
        truth(failsafe_events=["151.0 s radio failsafe: x"]),
        False,
        [fault("stream_stall", 150.0, 0.4)],
        None,
        "aborted (landed safely)",
        "without",
    ),
    (
        "blind landing after a slam-server kill",
        truth(failsafe_events=["154.0 s radio failsafe"]),
        False,
        [fault("slam_server_kill", 150.0, 1.0)],
        None,
        "landed by failsafe as expected",
        "slam_server_kill",
    ),
    ("gave up without a failsafe", truth(), False, [], None, "aborted (landed safely)", "timeout"),
    ("still armed", truth(armed_at_end=True), False, [], None, "lost", "not down"),
    ("flew away", truth(max_distance_from_path_m=2.5), True, [], LAND, "lost", "2.50 m"),
    ("hard touchdown", truth(touchdowns_mps=[0.3, 0.8]), True, [], LAND, "lost", "touchdown"),
    (
        "flew away under control, then a failsafe",
        truth(
            failsafe_events=["150.3 s radio failsafe: x"],
            max_distance_from_path_m=2.6,
            max_distance_under_control_m=2.2,
        ),
        False,
        [fault("ground_station_kill", 150.0)],
        None,
        "lost",
        "2.20 m from its path under control",
    ),
    (
        "blind landing drifts past the radius after a kill: on the ground, drift named",
        truth(
            failsafe_events=["150.3 s radio failsafe: x"],
            max_distance_from_path_m=2.6,
            max_distance_under_control_m=0.5,
        ),
        False,
        [fault("ground_station_kill", 150.0)],
        None,
        "landed by failsafe as expected",
        "blind landing drifted 2.60 m",
    ),
    (
        "blind landing drifts past the radius after a slam-server kill",
        truth(
            failsafe_events=["154.0 s radio failsafe"],
            max_distance_from_path_m=2.9,
            max_distance_under_control_m=0.4,
        ),
        False,
        [fault("slam_server_kill", 150.0, 1.7)],
        None,
        "landed by failsafe as expected",
        "drifted 2.90 m",
    ),
    (
        "an unexplained failsafe that drifts past the radius is lost",
        truth(
            failsafe_events=["170.0 s radio failsafe"],
            max_distance_from_path_m=2.3,
            max_distance_under_control_m=0.4,
        ),
        False,
        [],
        None,
        "lost",
        "no fault explains",
    ),
]


@pytest.mark.parametrize(
    "name,tr,completed,faults,land,outcome,reason", CASES, ids=[c[0] for c in CASES]
)
def test_outcome(name, tr, completed, faults, land, outcome, reason):
    got, why = judge(tr, completed, faults, TAKEOFF, land, "timeout waiting")
    assert got == outcome, (name, why)
    assert reason in why
