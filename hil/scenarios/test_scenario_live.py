"""Closed-loop HIL through the real firmware in real time: ground station -> HTTP -> WiFi-bridge
emulator -> firmware image in simavr (lock-step with) -> RC pulses -> FC emulator -> MAVLink back.

The ground station is hilrig.ground_station (signed PUT /control at 50 Hz, sticks from the
ground-truth pilot): the position source is the emulator's truth, standing in for slam-server +
quad-control, which had not landed when this was written. Everything between the HTTP request and
the craft's motion is the real system or its emulator.

  scenario 1  take off, hold 1.7 m for 30 s            -> hold error, HTTP->PWM latency
  scenario 7  malformed HTTP / forged / replayed requests at the bridge during a hover
              -> the right status for each, the craft keeps holding, no failsafe
  scenario 3  (live) the ground-station thread is killed during the hover -> firmware failsafe ->
              APM LAND -> on the ground, disarmed (touchdown speed reported; target tracked in
              test_scenario3_failsafe.py)
Reports: test-artifacts/hil/scenario1_hold.json, scenario7_bad_http.json, scenario3_live.json.
"""

from __future__ import annotations

import json
import math
import socket
import time

import numpy as np
import pytest
from arduino.simavr_session import firmware_elf
from fc_emulator import QuadParams
from hilrig.flight import Leg
from hilrig.ground_station import GroundStation
from hilrig.paths import artifacts_dir, find_binary

pytestmark = pytest.mark.hil

KEY = bytes(range(0x11, 0x21))
HOLD = (0.0, 0.0, -1.7)
HOLD_TOLERANCE_M = 0.15  # issue target: within +-0.15 m of the goal after settling
# "Never flying away": the craft stays within 1 m of where the fault hit (a small indoor room).
FLYAWAY_RADIUS_M = 1.0
SETTLE_S = 8.0  # arm gesture (2.4 s) + climb to 1.7 m + settling
# Indoor disturbances the position loop must reject (fc_emulator.quad_model): 0.15 m/s^2 air
# currents with 2 s correlation (a draft of ~0.5 m/s on the frame) and a 0.5 / -0.3 deg level-trim
# error of the APM.
DISTURBED = QuadParams(
    gust_accel_std_mss=0.15, gust_tau_s=2.0, trim_error_deg=(0.5, -0.3), disturbance_seed=7
)


def _need_rig():
    if find_binary("fw_sim") is None or firmware_elf() is None:
        pytest.skip(
            "fw_sim (hil/arduino) or the firmware image is not built: make build / make firmware"
        )


def _rig_and_bridge(tmp_path):
    from hilrig.live_rig import LiveRig
    from provision_key import key_record
    from rgbd_protocol.control_bridge import WifiBridgeEmulator

    rig = LiveRig(key_record(KEY), quad_params=DISTURBED, workdir=tmp_path)
    rig.start()
    bridge = WifiBridgeEmulator(rig.transact).start()
    return rig, bridge


def _hold_errors(history, from_us, to_us):
    sel = [s for s in history if from_us <= s.t_us <= to_us]
    horiz = [math.hypot(s.pos_ned_m[0] - HOLD[0], s.pos_ned_m[1] - HOLD[1]) for s in sel]
    vert = [abs(s.pos_ned_m[2] - HOLD[2]) for s in sel]
    err3 = [math.hypot(h, v) for h, v in zip(horiz, vert, strict=False)]
    return {
        "max_m": max(err3),
        "rms_m": float(np.sqrt(np.mean(np.square(err3)))),
        "max_horizontal_m": max(horiz),
        "max_vertical_m": max(vert),
        "samples": len(sel),
    }


def _latency(rig) -> dict:
    t = rig.timings()
    fw = np.array([x.reply_end_us - x.injected_us for x in t]) / 1000
    pwm = (
        np.array([x.first_pulse_after_us - x.reply_end_us for x in t if x.first_pulse_after_us])
        / 1000
    )
    return {
        "serial_and_firmware_median_ms": float(np.median(fw)),
        "reply_to_next_pwm_frame_median_ms": float(np.median(pwm)),
        "serial_in_to_pwm_median_ms": float(np.median(fw) + np.median(pwm)),
    }


def test_scenario1_takeoff_and_hold_30s(tmp_path):
    _need_rig()
    rig, bridge = _rig_and_bridge(tmp_path)
    try:
        gs = GroundStation(bridge.port, KEY, rig, [Leg(HOLD, 0.0, 1e9)]).start()
        assert rig.wait_sim((SETTLE_S + 30.0) * 1e6, timeout_s=240), "rig fell too far behind"
        gs.kill()
        hist = rig.history()
        err = _hold_errors(hist, SETTLE_S * 1e6, (SETTLE_S + 30.0) * 1e6)
        report = {
            **err,
            **_latency(rig),
            "commands_sent": gs.stats.sent,
            "command_rate_hz": gs.stats.sent / (hist[-1].t_us / 1e6),
            "http_round_trip_median_ms": float(np.median(gs.stats.round_trip_ms)),
            "statuses": gs.stats.statuses,
            "realtime_factor": rig.realtime_factor,
            "lag_dropped_s": rig.lag_dropped_s,
            "position_source": "emulator ground truth (slam-server/quad-control not in loop)",
        }
    finally:
        bridge.close()
        rig.close()
    (artifacts_dir() / "scenario1_hold.json").write_text(json.dumps(report, indent=2))
    print("\nscenario 1 (hold 1.7 m, 30 s):", json.dumps(report))
    assert not [e for t, e in rig.fc.events if "failsafe" in e]
    assert err["max_m"] <= HOLD_TOLERANCE_M
    ok = report["statuses"].get(200, 0)
    # Occasional 504s (a request queued behind the other client's past the bridge's 250 ms) and 409s
    # (a late request overtaken by a newer sequence number) are the link working as designed.
    assert set(report["statuses"]) <= {200, 409, 504} and ok >= 0.95 * gs.stats.sent


WAYPOINTS = [(1.5, 0.0, -1.7), (1.5, 1.0, -1.7)]
WAYPOINT_TOLERANCE_M = 0.15
LAND_DESCENT_MPS = 0.3  # the ground station's own landing: slow enough for a soft touchdown


def test_scenario2_two_waypoints_and_land(tmp_path):
    _need_rig()
    plan = [
        Leg(HOLD, 0.0, SETTLE_S - 2.4),
        Leg(WAYPOINTS[0], 0.0, 8.0),
        Leg(WAYPOINTS[1], 0.0, 8.0),
        Leg(
            (WAYPOINTS[1][0], WAYPOINTS[1][1], 1.0),
            0.0,
            1e9,
            max_climb_mps=LAND_DESCENT_MPS,
            land=True,
        ),
    ]
    rig, bridge = _rig_and_bridge(tmp_path)
    try:
        gs = GroundStation(bridge.port, KEY, rig, plan).start()
        deadline = time.monotonic() + 120
        while gs.disarmed_sim_us is None and time.monotonic() < deadline:
            time.sleep(0.1)
        rig.wait_sim(rig.sim_us + 1e6, timeout_s=10)
        gs.kill()
        hist = rig.history()
        starts = list(gs.leg_started_sim_us)
        touchdowns = list(rig.fc.touchdowns_mps)
        events = list(rig.fc.events)
    finally:
        bridge.close()
        rig.close()
    assert gs.disarmed_sim_us is not None, "never landed"
    arrivals = []
    for i, wp in enumerate(WAYPOINTS):
        leg_end = starts[i + 2]
        s = min(hist, key=lambda h: abs(h.t_us - leg_end))
        arrivals.append(math.dist(s.pos_ned_m, wp))
    report = {
        "waypoint_errors_at_leg_end_m": arrivals,
        "touchdown_vertical_speed_mps": touchdowns[-1] if touchdowns else None,
        "touchdown_xy_m": hist[-1].pos_ned_m[:2],
        "flight_time_s": gs.disarmed_sim_us / 1e6,
        "commands_sent": gs.stats.sent,
        "statuses": gs.stats.statuses,
        "position_source": "emulator ground truth (slam-server/quad-control not in loop)",
    }
    (artifacts_dir() / "scenario2_waypoints.json").write_text(json.dumps(report, indent=2))
    print("\nscenario 2 (two waypoints and land):", json.dumps(report))
    assert all(e <= WAYPOINT_TOLERANCE_M for e in arrivals)
    assert len(touchdowns) == 1 and touchdowns[0] <= 0.5
    assert report["statuses"].get(200, 0) >= 0.95 * gs.stats.sent
    assert math.dist(hist[-1].pos_ned_m[:2], WAYPOINTS[1][:2]) <= 0.3
    assert not [e for t, e in events if "failsafe" in e]


# (raw bytes sent to the bridge, HTTP status expected back). Lines reaching the firmware are
# answered by it (docs/protocol-control.md); the rest by the bridge's HTTP parser.
def _attacks(seq_base: int):
    from rgbd_protocol.control import build_control_request

    good = build_control_request(KEY, seq_base, True, 1500, 1500, 1500, 1500)
    forged = good[:-16] + ("0" * 16)
    wrong_key = build_control_request(bytes(16 * [7]), seq_base + 1, True, 1500, 1500, 2000, 1500)
    out_of_range = build_control_request(KEY, 4_000_000_000, True, 1500, 1500, 1500, 1500)
    out_of_range = out_of_range.replace("thr=1500", "thr=2500")  # MAC then fails first or range
    replay = build_control_request(KEY, 1, True, 1500, 1500, 1750, 1500)

    def http(line):
        method, target = line.split(" ", 1)
        return f"{method} {target} HTTP/1.1\r\nHost: craft\r\n\r\n".encode()

    return [
        ("garbage", b"\x00\xff\x13garbage\r\n\r\n", 400),
        ("bad_http_version", b"PUT /control HTTP/7.0\r\n\r\n", 505),
        ("forged_mac", http(forged), 401),
        ("wrong_key", http(wrong_key), 401),
        ("replayed_seq", http(replay), 409),
        ("tampered_field", http(out_of_range), 401),
        ("unknown_path", http("GET /motors"), 404),
        ("wrong_method", http("DELETE /control"), 405),
        ("line_too_long", http("GET /status?" + "a" * 140), 414),
        ("status_read", http("GET /status"), 200),
    ]


def _raw(port, data: bytes) -> int | None:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            s.sendall(data)
            first = s.recv(4096).split(b"\r\n", 1)[0].split()
            return int(first[1]) if len(first) >= 2 else None
    except (OSError, ValueError):
        return None


def test_scenario7_bad_http_then_scenario3_ground_station_killed(tmp_path):
    _need_rig()
    rig, bridge = _rig_and_bridge(tmp_path)
    try:
        gs = GroundStation(bridge.port, KEY, rig, [Leg(HOLD, 0.0, 1e9)]).start()
        assert rig.wait_sim(SETTLE_S * 1e6, timeout_s=120)
        attack_from = rig.sim_us
        results = {}
        rounds = 0
        while rig.sim_us < attack_from + 8e6:
            for name, data, _want in _attacks(gs.seqs.next() + 1000):
                got = _raw(bridge.port, data)
                results.setdefault(name, set()).add(got)
            rounds += 1
        attack_to = rig.sim_us
        err7 = _hold_errors(rig.history(), attack_from, attack_to)
        # Scenario 3, live: the ground station dies mid-hover.
        kill_us = rig.sim_us
        gs.kill()
        rig.wait_sim(kill_us + 14e6, timeout_s=120)
        hist = rig.history()
        fc_events = list(rig.fc.events)
        touchdowns = list(rig.fc.touchdowns_mps)
        final = hist[-1]
    finally:
        bridge.close()
        rig.close()
    expected = {name: want for name, _, want in _attacks(1)}
    report7 = {
        "attack_rounds": rounds,
        "statuses": {k: sorted(v, key=str) for k, v in results.items()},
        **err7,
        "ground_station_statuses": gs.stats.statuses,
        "bridge_counts": bridge.counts,
    }
    (artifacts_dir() / "scenario7_bad_http.json").write_text(
        json.dumps(report7, indent=2, default=str)
    )
    print("\nscenario 7 (bad HTTP at the bridge):", json.dumps(report7, default=str))
    after = [s for s in hist if s.t_us >= kill_us]
    at_kill = min(hist, key=lambda s: abs(s.t_us - kill_us))
    alt_at_kill = at_kill.altitude_m
    fs = [t for t, e in fc_events if e.startswith("radio failsafe") and t > kill_us]
    disarm = [t for t, e in fc_events if e.startswith("disarmed") and t > kill_us]
    report3 = {
        "altitude_at_kill_m": alt_at_kill,
        "apm_radio_failsafe_after_kill_ms": (fs[0] - kill_us) / 1000 if fs else None,
        "disarmed_after_kill_s": (disarm[0] - kill_us) / 1e6 if disarm else None,
        "touchdown_vertical_speed_mps": touchdowns[-1] if touchdowns else None,
        "max_altitude_after_kill_m": max(s.altitude_m for s in after),
        "max_horizontal_drift_m": max(
            math.hypot(s.pos_ned_m[0] - at_kill.pos_ned_m[0], s.pos_ned_m[1] - at_kill.pos_ned_m[1])
            for s in after
        ),
    }
    (artifacts_dir() / "scenario3_live.json").write_text(json.dumps(report3, indent=2))
    print("\nscenario 3 live (ground station killed):", json.dumps(report3))
    for name, want in expected.items():
        assert results[name] == {want}, (name, results[name])
    assert not [e for t, e in fc_events if "failsafe" in e and t < kill_us]
    assert err7["max_m"] <= HOLD_TOLERANCE_M
    # Scenario 3: landed and disarmed, never climbed, no fly-away.
    assert not final.armed and final.altitude_m == 0.0
    assert report3["max_altitude_after_kill_m"] <= alt_at_kill + 0.05
    # Without a position source the APM's LAND only holds the attitude level, so the trim error and
    # the gusts carry the craft off during the ~5 s to the ground: drift, not a fly-away.
    assert report3["max_horizontal_drift_m"] < FLYAWAY_RADIUS_M


# Scenario 5: the WiFi link between ground station and bridge degraded. 20 ms one-way delay with
# 10 ms jitter is a busy 2.4 GHz channel; 2 % of the segments needing a retransmission (>= 200 ms
# TCP RTO) is a poor one. Either outcome is safe: holding within tolerance, or failsafe -> landed.
DEGRADED = dict(delay_ms=20.0, jitter_ms=10.0, loss=0.02, seed=5)


def test_scenario5_degraded_control_link(tmp_path):
    from hilrig.link_proxy import LinkImpairment, LinkProxy

    _need_rig()
    rig, bridge = _rig_and_bridge(tmp_path)
    try:
        with LinkProxy(bridge.port, LinkImpairment(**DEGRADED)) as link:
            gs = GroundStation(link.port, KEY, rig, [Leg(HOLD, 0.0, 1e9)]).start()
            assert rig.wait_sim((SETTLE_S + 20.0) * 1e6, timeout_s=180)
            gs.kill()
            stalls, chunks = link.stalls, link.chunks
        # If the failsafe fired, give the craft time to land.
        if any("failsafe" in e for _, e in rig.fc.events):
            rig.wait_sim(rig.sim_us + 12e6, timeout_s=60)
        hist = rig.history()
        events = list(rig.fc.events)
    finally:
        bridge.close()
        rig.close()
    failsafe = [t for t, e in events if e.startswith("radio failsafe")]
    final = hist[-1]
    excursion = max(math.hypot(s.pos_ned_m[0], s.pos_ned_m[1]) for s in hist)
    report = {
        "impairment": DEGRADED,
        "retransmission_stalls": stalls,
        "chunks": chunks,
        "outcome": "landed after failsafe" if failsafe else "holding",
        "apm_failsafe_s": failsafe[0] / 1e6 if failsafe else None,
        "max_horizontal_excursion_m": excursion,
        "statuses": gs.stats.statuses,
        "http_round_trip_median_ms": float(np.median(gs.stats.round_trip_ms)),
        "http_round_trip_p95_ms": float(np.percentile(gs.stats.round_trip_ms, 95)),
    }
    if not failsafe:
        report.update(_hold_errors(hist, SETTLE_S * 1e6, (SETTLE_S + 20.0) * 1e6))
    (artifacts_dir() / "scenario5_degraded_control.json").write_text(json.dumps(report, indent=2))
    print("\nscenario 5 (degraded control link):", json.dumps(report))
    assert excursion < FLYAWAY_RADIUS_M  # never flies away
    if failsafe:
        assert not final.armed and final.altitude_m == 0.0
    else:
        assert report["max_m"] <= HOLD_TOLERANCE_M
