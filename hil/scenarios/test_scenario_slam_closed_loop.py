"""Closed-loop flights with SLAM in the loop (hilrig.slam_flight): the real rgbd-streamer (fed by
the live Kinect emulator through fakenect), slam-server and quad-control fly the real firmware in
simavr and the FC emulator. The operator uses quad-control's dashboard API; emulator truth only
scores.

  scenario 1  take off, hold 1.7 m for 30 s          -> hold error (truth), ATE, latency per stage
  scenario 2  take off, hold, two waypoints, land    -> waypoint errors, touchdown speed, ATE,
                                                        latency
  scenario 3  (SLAM loop) quad-control killed in the hover -> firmware failsafe -> APM LAND
  scenario 4  the stream link (both sockets) drops for 1 s mid-hover and comes back
  scenario 5  degraded stream link (20 +- 10 ms, 2 % loss stalls of 200 ms) during a hover
  scenario 6  blank frames from the Kinect mid-hover (the streamer drops them)
  scenario 8  turns in place: +90, -90, -90, +90 deg with holds between (the IMU rotation prior's
              case: a changing turn rate is what constant velocity predicts worst)
  load        take off and hold 30 s with two CPU burners (stress-ng) beside the ground station
Each fault scenario must end holding or landed, never flying away.
Reports: test-artifacts/hil/slam_loop_scenario{1..6}.json, slam_loop_load.json (printed by
make hil).
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from fc_emulator import QuadParams
from hilrig import missions
from hilrig.link_proxy import LinkImpairment
from hilrig.paths import artifacts_dir
from hilrig.slam_flight import (
    SlamFlight,
    SlamFlightOptions,
    camera_room_position,
    goal_in_room,
    hold_error,
    missing_load_tool,
    missing_parts,
)
from hilrig.verdict import judge_hold, map_resets
from kinect_emulator.live import match_capture_stamps

pytestmark = pytest.mark.hil

HOLD_TOLERANCE_M = 0.15  # issue target: within +-0.15 m of the goal after settling
WAYPOINT_TOLERANCE_M = 0.25  # quad-control arrives within 0.15 m of its SLAM estimate + SLAM drift
TOUCHDOWN_LIMIT_MPS = 0.5
# "Never flying away": within 2 m of where the fault hit, inside the 8 x 6 m room. The APM's LAND
# has no position hold without GPS or optical flow: its 0.5 deg trim error and the gusts drift the
# craft 0.6-1.5 m during the ~5 s failsafe descent (measured), and nothing on board can know.
FLYAWAY_RADIUS_M = 2.0
# Indoor disturbances (as the truth-piloted scenarios): 0.15 m/s^2 air currents, APM trim error.
DISTURBED = QuadParams(
    gust_accel_std_mss=0.15, gust_tau_s=2.0, trim_error_deg=(0.5, -0.3), disturbance_seed=7
)


def _flight(tmp_path, **options):
    missing = missing_parts()
    if missing:
        pytest.skip("not built / not installed: " + ", ".join(missing))
    return SlamFlight(tmp_path, SlamFlightOptions(**{"quad_params": DISTURBED, **options}))


@pytest.fixture
def flight(tmp_path):
    with _flight(tmp_path) as f:
        yield f


def _fault_outcome(flight, start_room, fault_sim_us) -> dict:
    """Where the fault left the craft: still holding (quad-control's state, truth error against the
    hold point) or landed, and the largest truth distance from the hold point since the fault."""
    goal = goal_in_room(start_room, (0.0, 0.0, missions.HOLD_HEIGHT_M))
    hist = [h for h in flight.rig.history() if h.t_us >= fault_sim_us]
    worst = max(
        float(np.linalg.norm(camera_room_position(h, flight.options.mount)[:2] - goal[:2]))
        for h in hist
    )
    st = flight.state()
    return {
        "state_after": st["state"],
        "last_event": st["last_event"],
        "landed": flight.rig.snapshot().landed,
        "max_horizontal_from_hold_point_m": round(worst, 3),
        "final_hold_error": hold_error(
            flight.rig.history(),
            goal,
            flight.options.mount,
            flight.rig.sim_us - 3e6,
            flight.rig.sim_us,
        ),
        "rejected_pose_jumps": st.get("rejected_poses"),
        "failsafe_events": [e for _, e in flight.rig.fc.events if "failsafe" in e],
    }


def _holding_or_landed(outcome) -> bool:
    holding = (
        outcome["state_after"] == "hold"
        and outcome["final_hold_error"]["max_m"] <= 2 * HOLD_TOLERANCE_M
    )
    return holding or outcome["landed"]


def _finish(flight, name: str, report: dict) -> dict:
    report.update(flight.scores())
    report["position_source"] = "SLAM (slam-server) through quad-control"
    (artifacts_dir() / f"{name}.json").write_text(json.dumps(report, indent=2, default=str))
    print(f"\n{name}:", json.dumps(report, default=str))
    return report


def test_slam_loop_scenario1_hold_30s(flight):
    to = missions.take_off(flight, progress=print)
    err = missions.hold(flight, to["start_room_m"], 30.0, progress=print)
    report = _finish(
        flight, "slam_loop_scenario1", {"hold": err, "realtime_factor": flight.rig.realtime_factor}
    )
    assert not [e for _, e in flight.rig.fc.events if "failsafe" in e]
    assert report["ate"].get("ate_rmse_m") is not None
    assert err["max_m"] <= HOLD_TOLERANCE_M, err


def test_slam_loop_scenario2_waypoints_and_land(flight):
    report = missions.scenario2(flight, progress=print)
    report = _finish(flight, "slam_loop_scenario2", report)
    assert not report["failsafe_events"]
    assert report["hold"]["max_m"] <= HOLD_TOLERANCE_M, report["hold"]
    for wp in report["waypoints"]:
        assert wp["max_m"] <= WAYPOINT_TOLERANCE_M, wp
    assert report["landing"]["touchdowns"] >= 1
    assert report["landing"]["touchdown_vertical_speed_mps"] <= TOUCHDOWN_LIMIT_MPS
    assert report["ate"].get("ate_rmse_m") is not None


def test_slam_loop_scenario3_ground_station_killed(flight):
    to = missions.take_off(flight, progress=print)
    flight.hold_for(missions.SETTLE_S)
    at_kill = camera_room_position(flight.rig.snapshot(), flight.options.mount)
    kill_sim_us = flight.rig.sim_us
    flight.kill_ground_station()
    end = time.monotonic() + 60
    while time.monotonic() < end and flight.rig.snapshot().armed:
        flight.hold_for(0.5)
    hist = [s for s in flight.rig.history() if s.t_us >= kill_sim_us]
    drift = max(
        float(((camera_room_position(s, flight.options.mount)[:2] - at_kill[:2]) ** 2).sum() ** 0.5)
        for s in hist
    )
    touchdowns = list(flight.rig.fc.touchdowns_mps)
    report = _finish(
        flight,
        "slam_loop_scenario3",
        {
            "height_at_kill_m": round(float(at_kill[2]), 3),
            "disarmed": not flight.rig.snapshot().armed,
            "landed_after_kill_s": round((hist[-1].t_us - kill_sim_us) / 1e6, 1),
            "max_horizontal_drift_m": round(drift, 3),
            "touchdown_vertical_speed_mps": touchdowns[-1] if touchdowns else None,
            "events": [e for _, e in flight.rig.fc.events],
            "start_room_m": list(to["start_room_m"]),
        },
    )
    assert report["disarmed"] and flight.rig.snapshot().landed
    assert drift < FLYAWAY_RADIUS_M
    assert touchdowns and max(touchdowns) <= TOUCHDOWN_LIMIT_MPS + 0.01


def _settle_outcome(flight, timeout_s: float = 40.0) -> None:
    """Waits until the craft holds with tracking or is on the ground disarmed (either is a safe end
    of a fault; quad-control's pose-jump gate may have chosen the blind landing)."""
    flight.wait_until(
        lambda s: (s["state"] == "hold" and s["tracking"])
        or (s["state"] == "disarmed" and not flight.rig.snapshot().armed),
        timeout_s=timeout_s,
        what="holding with tracking, or landed and disarmed",
    )


def test_slam_loop_scenario4_stream_link_dropped_and_restored(tmp_path):
    with _flight(tmp_path, stream_impairment=LinkImpairment()) as flight:
        to = missions.take_off(flight, progress=print)
        flight.hold_for(missions.SETTLE_S)
        t_fault = flight.rig.sim_us
        flight.sever_stream()
        flight.hold_for(1.0)
        flight.restore_stream()
        t_back = time.monotonic()
        _settle_outcome(flight)
        settled_s = round(time.monotonic() - t_back, 2)
        if flight.state()["state"] == "hold":
            flight.hold_for(8.0)
        out = _fault_outcome(flight, to["start_room_m"], t_fault)
        touchdowns = list(flight.rig.fc.touchdowns_mps)
        report = _finish(
            flight,
            "slam_loop_scenario4",
            {
                "outage_s": 1.0,
                "settled_after_restore_s": settled_s,
                "touchdown_vertical_speed_mps": max(touchdowns) if touchdowns else None,
                **out,
            },
        )
    assert not out["failsafe_events"]
    assert out["max_horizontal_from_hold_point_m"] < FLYAWAY_RADIUS_M
    assert _holding_or_landed(out), report


def test_slam_loop_scenario5_degraded_stream_link(tmp_path):
    bad = LinkImpairment(delay_ms=20.0, jitter_ms=10.0, loss=0.02, seed=5)
    # The WiFi configuration of docs/onboard.md: JPEG RGB + zstd-delta depth (~13x and ~6x smaller
    # than raw). With raw RGB a 900 KB frame spans ~15 chunks, so a third of the frames would hit a
    # 200 ms loss stall.
    with _flight(
        tmp_path, stream_impairment=bad, rgb_encoding="jpeg", depth_encoding="zstd-delta"
    ) as flight:
        report: dict = {"impairment": bad.__dict__}
        t0 = flight.rig.sim_us
        start = None
        try:
            to = missions.take_off(flight, progress=print)
            start = to["start_room_m"]
            report["hold"] = missions.hold(flight, start, 20.0, progress=print)
        except (TimeoutError, RuntimeError) as e:  # the mission could not go on: how did it end?
            report["mission_aborted"] = str(e)[:300]
        _settle_outcome(flight)
        took_off = start is not None
        if start is None:
            start = camera_room_position(flight.rig.history()[0], flight.options.mount)
        out = _fault_outcome(flight, start, t0)
        touchdowns = list(flight.rig.fc.touchdowns_mps)
        # quad-control's IMU + pose fusion across the stalls (docs/control.md "Estimator")
        report["estimator"] = flight.state().get("estimator")
        report = _finish(
            flight,
            "slam_loop_scenario5",
            {
                **report,
                "touchdown_vertical_speed_mps": max(touchdowns) if touchdowns else None,
                **out,
            },
        )
    # A craft that never took off holds perfectly: that is a failure of the flight, not a pass.
    assert took_off, f"never took off: {report.get('mission_aborted')}"
    assert out["max_horizontal_from_hold_point_m"] < FLYAWAY_RADIUS_M
    assert _holding_or_landed(out), report
    # The targets of the real-time SLAM issue: SLAM holds through the stalls, and so does the craft.
    assert report["ate"].get("ate_rmse_m") is not None and report["ate"]["ate_rmse_m"] <= 0.030, (
        report["ate"]
    )
    # Was a strict xfail until 3 Dec 2026 (0.158-0.169 m): met since the roll/pitch gains were
    # chosen for the shorter loop delay (hilrig/slam_flight.py HIL_CONTROLLER_GAINS; docs/hil.md).
    assert out["max_horizontal_from_hold_point_m"] <= HOLD_TOLERANCE_M, out


# Scenario 8: each turn faces another wall of the room (left, back to the front, right, front).
TURNS_CCW_DEG = (90.0, -90.0, -90.0, 90.0)
TURN_HOLD_S = 8.0


def test_slam_loop_scenario8_turns_in_place(flight):
    to = missions.take_off(flight, progress=print)
    start = to["start_room_m"]
    report: dict = {"hold": missions.hold(flight, start, 5.0, progress=print)}
    report["turns"] = [
        missions.turn(flight, start, yaw, TURN_HOLD_S, progress=print) for yaw in TURNS_CCW_DEG
    ]
    report["failsafe_events"] = [e for _, e in flight.rig.fc.events if "failsafe" in e]
    report["rejected_pose_jumps"] = flight.state().get("rejected_poses")
    prior = flight.options.imu_rotation_prior
    report["imu_rotation_prior"] = "default (on)" if prior is None else prior
    report = _finish(flight, "slam_loop_scenario8", report)
    assert not report["failsafe_events"]
    assert report["ate"].get("ate_rmse_m") is not None
    for t in report["turns"]:
        assert abs(t["true_turn_deg"] - t["yaw_ccw_deg"]) <= 2 * missions.TURN_DONE_DEG, t
        assert t["hold"]["max_m"] <= HOLD_TOLERANCE_M, t


def test_slam_loop_scenario6_blank_frames(tmp_path):
    # Render indices ~13 s into the flight at 30 fps (during the hold): 3 blank frames in a row,
    # then
    # 2 single ones.
    blanks = frozenset({390, 391, 392, 450, 510})
    with _flight(tmp_path, blank_frames=blanks) as flight:
        to = missions.take_off(flight, progress=print)
        t0 = flight.rig.sim_us
        err = missions.hold(flight, to["start_room_m"], 15.0, progress=print)
        out = _fault_outcome(flight, to["start_room_m"], t0)
        records = flight.kinect.records()
        received = match_capture_stamps(records, [int(f["capture_us"]) for f in flight.frames()])
        report = _finish(
            flight,
            "slam_loop_scenario6",
            {
                "blank_frames_rendered": sorted(r.index for r in records if r.index in blanks),
                "blank_frames_received": sorted(
                    r.index for r in received if r is not None and r.index in blanks
                ),
                "hold": err,
                **out,
            },
        )
    assert len(report["blank_frames_rendered"]) >= 3, (
        "the blank frames were not reached during the hold"
    )
    assert report["blank_frames_received"] == [], "blank frames reached the ground station"
    assert out["state_after"] == "hold" and not out["failsafe_events"]
    assert err["max_m"] <= 2 * HOLD_TOLERANCE_M


# The load scenario: two CPU-burning workers, one per core of the 2-core machine
# the rig was sized on, at the normal policy beside the ground station for the whole flight.
LOAD_CPU_BURNERS = 2
LOAD_HOLD_S = 30.0


def test_slam_loop_load_two_cpu_burners(tmp_path):
    """Take off and hold 30 s while `stress-ng --cpu 2` burns both cores. The ground station's
    real-time path (quad-control's frame / SLAM-link / firmware-link threads, slam-server's tracking
    thread: SCHED_RR) must hold: hold +-0.15 m, SLAM ATE <= 30 mm, 0 SLAM map resets. The rig
    (SCHED_RR above them, hilrig.realtime) must keep real time; if it did not, the run fails as
    "rig overloaded" and the other figures are not judged. Flown in make demo's conditions (no
    gusts, no trim error): scenario 1 holds the gusty case, this one isolates the load."""
    missing = missing_load_tool()
    if missing:
        pytest.skip("not installed: " + ", ".join(missing))
    with _flight(tmp_path, cpu_burners=LOAD_CPU_BURNERS, quad_params=QuadParams()) as flight:
        report: dict = {"cpu_burners": LOAD_CPU_BURNERS}
        try:
            to = missions.take_off(flight, progress=print)
            report["hold"] = missions.hold(flight, to["start_room_m"], LOAD_HOLD_S, progress=print)
        except (TimeoutError, RuntimeError) as e:
            report["aborted"] = str(e)[:300]
        report["failsafe_events"] = [e for _, e in flight.rig.fc.events if "failsafe" in e]
        report["realtime_factor"] = round(flight.rig.realtime_factor, 3)
        try:
            final_state = flight.state()
        except Exception:  # noqa: BLE001 - quad-control may have died; its log still counts
            final_state = None
        report = _finish(flight, "slam_loop_load", report)
        resets = map_resets(
            _log(tmp_path / "slam-server.log"), _log(tmp_path / "quad-control.log"), final_state
        )
    report["slam_link"] = resets
    checks = judge_hold(report, resets, flight.options.fps)
    report["verdict"] = [c.__dict__ for c in checks]
    (artifacts_dir() / "slam_loop_load.json").write_text(json.dumps(report, indent=2, default=str))
    lat = report["latency_ms"].get("capture_to_pwm", {})
    print(
        f"load scenario (load average {report['load_average']}): "
        f"camera->PWM median {lat.get('median_ms')} ms, "
        f"p95 {lat.get('p95_ms')} ms; scheduling {report['scheduling']}"
    )
    for c in checks:
        print("load scenario: " + c.line())
    rig, *targets = checks
    if not rig.passed:
        pytest.fail("rig overloaded (not a system fault): " + rig.line())
    assert not report["failsafe_events"], report["failsafe_events"]
    missed = [c.line() for c in targets if not c.passed]
    assert not missed, "; ".join(missed)


def _log(path) -> str | None:
    return path.read_text(errors="replace") if path.exists() else None


def test_slam_loop_slam_server_killed_and_restarted(tmp_path):
    """slam-server is SIGKILLed in the hover and a new one started on the same port 1 s later (a
    supervisor's restart, same arguments). The flight's map dies with the process but not its
    checkpoint (--checkpoint-dir, written within a second of data after every map change): the new
    server resumes quad-control's map from it (SlamHello.resumed), relocalises in the same map and
    reports poses in the same world frame, so the drift during the outage (lost-hold, neutral
    sticks, no pose) is observed and flown back instead of being anchored into a new map (before
    checkpoints: 0.39-0.61 m off the hold point). Asserted: the broken link logged with its cause,
    the map resumed from its checkpoint, no crash, the craft ends holding with tracking or landed,
    never climbing or flying away; the hold error after the restart is reported."""
    with _flight(tmp_path) as flight:
        to = missions.take_off(flight, progress=print)
        flight.hold_for(missions.SETTLE_S)
        t_fault = flight.rig.sim_us
        flight.kill_slam_server()
        flight.hold_for(1.0)
        flight.restart_slam_server()
        _settle_outcome(flight)
        if flight.state()["state"] == "hold":
            flight.hold_for(8.0)
        out = _fault_outcome(flight, to["start_room_m"], t_fault)
        qc_log = _log(tmp_path / "quad-control.log") or ""
        st = flight.state()
        server_log = _log(tmp_path / "slam-server.log") or ""
        report = _finish(
            flight,
            "slam_loop_slam_server_restart",
            {
                "outage_s": 1.0,
                "slam": st.get("slam"),
                "disconnect_causes": [
                    line for line in qc_log.splitlines() if "SLAM link: disconnected" in line
                ][:3],
                "resumed_from_checkpoint": [
                    line
                    for line in server_log.splitlines()
                    if "resumed from its checkpoint" in line
                ][:1],
                **out,
            },
        )
    assert report["disconnect_causes"], "the broken SLAM link was not logged with a cause"
    assert report["resumed_from_checkpoint"], (
        "the restarted slam-server did not resume the flight's map"
    )
    assert out["max_horizontal_from_hold_point_m"] < FLYAWAY_RADIUS_M
    holding = out["state_after"] == "hold" and report["slam"]["state"] == "tracking"
    assert holding or out["landed"], report
    # Never a climb: the height stays on the hold height (AltHold) or the craft is down.
    assert out["landed"] or out["final_hold_error"]["max_vertical_m"] <= HOLD_TOLERANCE_M, out
