"""Fast manoeuvres with SLAM in the loop (hilrig.manoeuvres): take off, hold, turn +180 and -180 deg
at 60 deg/s, dash 2 m forward and back at 1 m/s, turn +90 deg, a hold after each, land. The real
rgbd-streamer, slam-server and quad-control fly the real firmware in simavr and the FC emulator, in
scenario 1's gusts and trim error; quad-control flies its default position law.

Targets: SLAM ATE <= 30 mm, hold <= 0.15 m after each manoeuvre (truth, after
manoeuvres.MANOEUVRE_SETTLE_S), no failsafe. Flown with slam-server's default (a frame the tracker
cannot place starts a new segment of the same map) and with `--restart-when-lost off` (it stays
lost until relocalised). What SLAM did (frames lost, relocalised, new segments) is in the report
either way: test-artifacts/hil/slam_loop_fast_manoeuvres{,_segments_off}.json.
"""

from __future__ import annotations

import json

import pytest
from hilrig import manoeuvres
from hilrig.paths import artifacts_dir
from hilrig.slam_flight import SlamFlight, SlamFlightOptions, missing_parts
from test_scenario_slam_closed_loop import DISTURBED, HOLD_TOLERANCE_M

pytestmark = pytest.mark.hil

ATE_LIMIT_M = 0.030  # the SLAM target of every closed-loop scenario


def _fly(tmp_path, name: str, slam_server_args: tuple) -> dict:
    missing = missing_parts()
    if missing:
        pytest.skip("not built / not installed: " + ", ".join(missing))
    options = SlamFlightOptions(quad_params=DISTURBED, slam_server_args=slam_server_args)
    with SlamFlight(tmp_path, options) as flight:
        report = manoeuvres.fast_manoeuvres(flight, progress=print)
        report["slam_server_args"] = list(slam_server_args)
        report.update(flight.scores())
    (artifacts_dir() / f"{name}.json").write_text(json.dumps(report, indent=2, default=str))
    print(f"\n{name}:", json.dumps(report, default=str))
    return report


def _check(report: dict) -> None:
    misses = []
    if report["failsafe_events"]:
        misses.append(f"failsafe: {report['failsafe_events']}")
    ate = report["ate"].get("ate_rmse_m")
    if ate is None or ate > ATE_LIMIT_M:
        misses.append(f"SLAM ATE {ate} m (limit {ATE_LIMIT_M}; {report['ate']})")
    for m in report["manoeuvres"]:
        if m["hold"].get("max_m", 1e9) > HOLD_TOLERANCE_M:
            misses.append(f"hold after {m['request']}: {m['hold']} (limit {HOLD_TOLERANCE_M} m)")
    assert not misses, "; ".join(misses) + f"; SLAM {report.get('slam_tracking')}"


def test_slam_loop_fast_manoeuvres(tmp_path):
    _check(_fly(tmp_path, "slam_loop_fast_manoeuvres", ()))


def test_slam_loop_fast_manoeuvres_segments_off(tmp_path):
    _check(
        _fly(
            tmp_path,
            "slam_loop_fast_manoeuvres_segments_off",
            ("--restart-when-lost", "off"),
        )
    )
