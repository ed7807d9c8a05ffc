"""HIL scenario 3: ground station killed -> firmware failsafe -> APM radio failsafe -> safe landing.

Real firmware image in simavr (hil/arduino fw_sim) + FC emulator; the ground station is a replay of
the commands a ground-truth pilot sent in a dry run (arm gesture, take off, hold 1.7 m), signed with
the craft's key exactly as quad-control signs them. At T_kill the commands stop (the ground station
process died). Everything after that is the firmware's and the APM's doing.

Pass 1 runs the firmware without telemetry; the FC emulator then flies on the measured pulses and
its MAVLink bytes are fed back in pass 2, which must produce the same pulses (outputs independent of
telemetry) and replies carrying the emulator's attitude.

Reported (test-artifacts/hil/scenario3_failsafe.json): failsafe onset after the last command,
time to the APM's radio failsafe, touchdown vertical speed, drift, time to disarm. The same failsafe
pulses are also flown by an APM in Stabilize (scenario3_failsafe_stabilize.json).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from arduino.simavr_session import Scenario, firmware_elf
from fc_emulator import FlightControllerEmulator, fly
from fc_emulator.emulator import FS_COUNTER, FS_THR_VALUE_US, LAND_SPEED_MPS, RC_READ_PERIOD_US
from fw_limits import FW_LIMITS
from hilrig.flight import Leg, fly_plan
from hilrig.paths import artifacts_dir, find_binary
from hilrig.pilot import ARM_STICKS_US

pytestmark = pytest.mark.hil

KEY = bytes(range(0x11, 0x21))  # the test craft's 16-byte control key
BOOT_US = 200_000  # first command after the firmware has booted
ARM_GESTURE_S = 2.4  # ArduCopter needs 2 s; 0.4 s margin for the PWM frame delay
HOLD_ALT_M = 1.7
FLY_S = 14.0  # take off (~4 s) + hold; the ground station dies at the end
AFTER_KILL_S = 14.0  # onset 0.25 s + APM Land from 1.7 m at 0.5 m/s (~4.6 s) + margin
THROTTLE_CHANNEL = 3  # fw_sim numbers the RC outputs 1..4: roll, pitch, throttle, yaw
FW_SIM_TIMEOUT_S = 300.0  # 28 simulated s run in ~8 s idle; a loaded machine may be 10x slower
# The firmware's failsafe timing and RC frame (firmware/core/limits.h, read by fw_limits).
FW_FAILSAFE_TIMEOUT_MS = FW_LIMITS["kFailsafeTimeoutMs"]
FW_FRAME_MS = FW_LIMITS["kPwmFramePeriodUs"] / 1000
APM_FS_COUNTER_MS = (
    FS_COUNTER * RC_READ_PERIOD_US / 1000
)  # the emulated APM's low-throttle debounce


def _ground_station_commands() -> list[tuple[int, tuple[int, int, int, int], bool]]:
    """(t_us, sticks, arm) at 50 Hz from the dry run: the commands quad-control would have sent."""
    cmds = []
    fc = FlightControllerEmulator(start_us=BOOT_US)
    fly(fc, None, 0.0)
    t = BOOT_US
    end = BOOT_US + int(ARM_GESTURE_S * 1e6)
    while t < end:
        t += RC_READ_PERIOD_US
        fc.feed_rc(ARM_STICKS_US, t)
        fc.advance_to(t)
        cmds.append((t, ARM_STICKS_US, True))
    assert fc.armed, "dry run did not arm"
    fly_plan(
        fc,
        [Leg((0.0, 0.0, -HOLD_ALT_M), 0.0, FLY_S)],
        on_sticks=lambda tt, s: cmds.append((tt, tuple(s), True)),
    )
    return cmds


def _script(cmds, kill_us: int, end_us: int, mavlink=()) -> Scenario:
    from rgbd_protocol.control import SequenceCounter, build_control_request

    seqs = SequenceCounter()
    sc = Scenario()
    for t, (r, p, th, y), armed in cmds:
        if t >= kill_us:
            break
        sc.req(t, build_control_request(KEY, seqs.next(), armed, r, p, th, y))
    for t, data in mavlink:
        sc.mav(t, data)
    sc.end(end_us)
    return sc


def _fly_on_pulses(pulses, end_us: int, sink=None):
    """FC emulator driven by the firmware's measured pulses; returns it and an altitude trace."""
    fc = FlightControllerEmulator(sink=sink)
    trace = []
    for p in sorted(pulses, key=lambda q: q.end_us):
        t = int(p.end_us)
        fc.advance_to(t)
        fc.feed_pulse(p.rc_index, p.width_us, t)
        if not trace or t - trace[-1][0] >= 20_000:
            s = fc.snapshot()
            trace.append((t, s.pos_ned_m, s.armed))
    fc.advance_to(end_us)
    return fc, trace


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    if find_binary("fw_sim") is None or firmware_elf() is None:
        pytest.skip(
            "fw_sim (hil/arduino) or the firmware image is not built: "
            "run make build / make firmware"
        )
    from provision_key import key_record

    work = tmp_path_factory.mktemp("scenario3")
    cmds = _ground_station_commands()
    kill_us = cmds[-1][0] + RC_READ_PERIOD_US
    end_us = kill_us + int(AFTER_KILL_S * 1e6)
    eeprom = key_record(KEY)
    pass1 = _script(cmds, kill_us, end_us).run(eeprom, work, timeout_s=FW_SIM_TIMEOUT_S)
    mav = []
    fc, trace = _fly_on_pulses(pass1.pulses, end_us, sink=lambda t, d: mav.append((t, d)))
    pass2 = _script(cmds, kill_us, end_us, mavlink=mav).run(
        eeprom, work, timeout_s=FW_SIM_TIMEOUT_S
    )
    return dict(
        cmds=cmds,
        kill_us=kill_us,
        end_us=end_us,
        pass1=pass1,
        pass2=pass2,
        fc=fc,
        trace=trace,
        work=work,
    )


def _metrics(sc) -> dict:
    kill_us, fc, trace = sc["kill_us"], sc["fc"], sc["trace"]
    last_cmd_us = max(t for t, _, _ in sc["cmds"] if t < kill_us)
    last_thr = [c for t, c, _ in sc["cmds"] if t < kill_us][-1][2]
    thr = [
        p for p in sc["pass1"].pulses if p.channel == THROTTLE_CHANNEL and p.rise_us > last_cmd_us
    ]
    onset = next(p for p in thr if abs(p.width_us - last_thr) > 3)  # first pulse off the command
    below = next(p for p in thr if p.width_us < FS_THR_VALUE_US)  # what the APM takes as failsafe
    fs_events = [t for t, e in fc.events if e.startswith("radio failsafe") and t > kill_us]
    disarm = [t for t, e in fc.events if e.startswith("disarmed") and t > kill_us]
    at_kill = min(trace, key=lambda r: abs(r[0] - kill_us))[1]
    after = [r[1] for r in trace if r[0] >= kill_us]
    max_alt_after = max(-p[2] for p in after)
    drift = max(math.hypot(p[0] - at_kill[0], p[1] - at_kill[1]) for p in after)
    touch = [v for v in fc.touchdowns_mps]
    return {
        "altitude_at_kill_m": -at_kill[2],
        "firmware_failsafe_onset_after_last_command_ms": (onset.rise_us - last_cmd_us) / 1000,
        "throttle_below_fs_thr_after_kill_ms": (below.rise_us - kill_us) / 1000,
        "apm_radio_failsafe_after_kill_ms": (fs_events[0] - kill_us) / 1000 if fs_events else None,
        "touchdown_vertical_speed_mps": touch[-1] if touch else None,
        "touchdowns": len(touch),
        "disarmed_after_kill_s": (disarm[0] - kill_us) / 1e6 if disarm else None,
        "max_altitude_after_kill_m": max_alt_after,
        "max_horizontal_drift_m": drift,
        "events": [(t / 1e6, e) for t, e in fc.events],
    }


def test_scenario3_lands_safely(scenario):
    m = _metrics(scenario)
    (artifacts_dir() / "scenario3_failsafe.json").write_text(json.dumps(m, indent=2))
    print(
        "\nscenario 3 (ground station killed):",
        json.dumps({k: v for k, v in m.items() if k != "events"}),
    )
    assert m["altitude_at_kill_m"] == pytest.approx(HOLD_ALT_M, abs=0.15)
    # Firmware: 250 ms without a valid command (kFailsafeTimeoutMs), seen at the next 20 ms frame.
    onset_ms = m["firmware_failsafe_onset_after_last_command_ms"]
    assert FW_FAILSAFE_TIMEOUT_MS <= onset_ms <= FW_FAILSAFE_TIMEOUT_MS + 2 * FW_FRAME_MS + 5
    assert m["apm_radio_failsafe_after_kill_ms"] is not None
    assert m["disarmed_after_kill_s"] is not None and not scenario["fc"].armed
    assert scenario["fc"].snapshot().altitude_m == 0.0
    assert m["max_altitude_after_kill_m"] <= m["altitude_at_kill_m"] + 0.05  # never climbs away
    assert m["max_horizontal_drift_m"] < 0.3
    assert m["touchdowns"] == 1


def test_scenario3_touchdown_speed_within_target(scenario):
    # The firmware steps to kFailsafeThrottleUs (950 us) at the failsafe onset: the APM's LAND
    # takes over after FS_COUNTER low frames and flies the whole descent at LAND_SPEED.
    m = _metrics(scenario)
    assert m["touchdown_vertical_speed_mps"] <= LAND_SPEED_MPS + 0.01, m
    handover_ms = (
        FW_FAILSAFE_TIMEOUT_MS + 2 * FW_FRAME_MS + APM_FS_COUNTER_MS + 5
    )  # onset + FS_COUNTER
    assert m["apm_radio_failsafe_after_kill_ms"] <= handover_ms


# Stabilize: the same firmware failsafe output (the firmware does not know the APM's flight mode)
# must land a craft hovering in Stabilize too, where the throttle is the collective: any throttle
# below hover on the way down would be a fall, so only a prompt hand-over to LAND is safe.
STAB_HOVER_P_US_PER_M = 120.0  # toy pilot holding altitude on the collective (Stabilize)
STAB_HOVER_D_US_PER_MPS = 150.0
STAB_HOVER_I_US_PER_M_S = 40.0


def _stabilize_hover(fc, alt_m: float, duration_s: float) -> tuple[int, int, int, int]:
    """Flies `fc` (armed, Stabilize) to `alt_m` on the collective with a PID pilot at 50 Hz;
    returns the last stick frame sent."""
    integ = 0.0
    sticks = (1500, 1500, 1000, 1500)
    for _ in range(int(duration_s * 1e6 / RC_READ_PERIOD_US)):
        s = fc.snapshot()
        err = alt_m - s.altitude_m
        integ += err * RC_READ_PERIOD_US * 1e-6
        thr = 1500 + STAB_HOVER_P_US_PER_M * err + STAB_HOVER_I_US_PER_M_S * integ
        thr -= STAB_HOVER_D_US_PER_MPS * s.climb_rate_mps
        sticks = (1500, 1500, int(min(1750, max(1000, thr))), 1500)
        t = fc.t_us + RC_READ_PERIOD_US
        fc.feed_rc(sticks, t)
        fc.advance_to(t)
    return sticks


def test_scenario3_failsafe_output_also_lands_a_craft_in_stabilize(scenario):
    from fc_emulator.emulator import FcOptions, FlightMode

    # GIVEN a craft hovering at HOLD_ALT_M in Stabilize (armed by the same gesture)
    fc = FlightControllerEmulator(start_us=BOOT_US, options=FcOptions(mode=FlightMode.STABILIZE))
    t = BOOT_US
    while t < BOOT_US + int(ARM_GESTURE_S * 1e6):
        t += RC_READ_PERIOD_US
        fc.feed_rc(ARM_STICKS_US, t)
        fc.advance_to(t)
    assert fc.armed
    last = _stabilize_hover(fc, HOLD_ALT_M, FLY_S)
    last_cmd_stab = fc.t_us
    alt_at_kill = fc.snapshot().altitude_m
    # WHEN its commands stop: the firmware repeats the last command until its failsafe onset, then
    # outputs exactly what the real image output in pass 1 from its onset on (time-shifted)
    cmds, p1 = scenario["cmds"], scenario["pass1"].pulses
    last_cmd_us = max(t for t, _, _ in cmds if t < scenario["kill_us"])
    last_thr = [c for tt, c, _ in cmds if tt < scenario["kill_us"]][-1][2]
    thr = [p for p in p1 if p.channel == THROTTLE_CHANNEL and p.rise_us > last_cmd_us]
    onset = next(p for p in thr if abs(p.width_us - last_thr) > 3)
    # The roll and pitch pulses of the same frame precede it by < 4 ms; the previous frame ended
    # > 10 ms before.
    frame_start = onset.rise_us - 5000
    shift = last_cmd_stab - last_cmd_us
    t = last_cmd_stab
    while t + RC_READ_PERIOD_US < frame_start + shift:
        t += RC_READ_PERIOD_US
        fc.feed_rc(last, t)
        fc.advance_to(t)
    for p in sorted((q for q in p1 if q.rise_us >= frame_start), key=lambda q: q.end_us):
        tt = int(p.end_us + shift)
        fc.advance_to(tt)
        fc.feed_pulse(p.rc_index, p.width_us, tt)
    fc.advance_to(int(scenario["end_us"] + shift))
    kill = last_cmd_stab + RC_READ_PERIOD_US
    fs = [tt for tt, e in fc.events if e.startswith("radio failsafe") and tt > kill]
    disarm = [tt for tt, e in fc.events if e.startswith("disarmed") and tt > kill]
    report = {
        "altitude_at_kill_m": alt_at_kill,
        "apm_radio_failsafe_after_kill_ms": (fs[0] - kill) / 1000 if fs else None,
        "touchdown_vertical_speed_mps": fc.touchdowns_mps[-1] if fc.touchdowns_mps else None,
        "touchdowns": len(fc.touchdowns_mps),
        "disarmed_after_kill_s": (disarm[0] - kill) / 1e6 if disarm else None,
    }
    (artifacts_dir() / "scenario3_failsafe_stabilize.json").write_text(json.dumps(report, indent=2))
    print("\nscenario 3 in Stabilize:", json.dumps(report))
    # THEN the APM's LAND lands it at LAND_SPEED and disarms
    assert alt_at_kill == pytest.approx(HOLD_ALT_M, abs=0.15)
    assert report["touchdowns"] == 1
    assert report["touchdown_vertical_speed_mps"] <= LAND_SPEED_MPS + 0.01, report
    assert report["disarmed_after_kill_s"] is not None and not fc.armed


# The soft-UART receiving telemetry (INT0 + Timer2 ISRs) delays the PWM sequencer's ISR by up to a
# few microseconds; RC receivers jitter by as much, and ArduPilot's 20 us stick dead zone absorbs
# it.
PWM_JITTER_TOLERANCE_US = 10.0


def test_scenario3_outputs_do_not_depend_on_telemetry_and_replies_carry_it(scenario):
    p1, p2 = scenario["pass1"].pulses, scenario["pass2"].pulses
    assert len(p1) == len(p2)
    assert all(a.channel == b.channel for a, b in zip(p1, p2, strict=False))
    width_jitter = max(abs(a.width_us - b.width_us) for a, b in zip(p1, p2, strict=False))
    rise_jitter = max(abs(a.rise_us - b.rise_us) for a, b in zip(p1, p2, strict=False))
    print(
        f"\nscenario 3: PWM jitter caused by telemetry: width {width_jitter:.1f} us, "
        f"edge {rise_jitter:.1f} us over {len(p1)} pulses"
    )
    assert width_jitter <= PWM_JITTER_TOLERANCE_US and rise_jitter <= PWM_JITTER_TOLERANCE_US
    from rgbd_protocol.control import parse_reply

    replies = [(r.end_us, parse_reply(r.text)) for r in scenario["pass2"].replies]
    assert all(rep.status == 200 for _, rep in replies)
    with_att = [(t, rep) for t, rep in replies if rep.att_age_ms is not None]
    assert len(with_att) > 0.8 * len(replies)
    ages = np.array([rep.att_age_ms for _, rep in with_att])
    assert np.median(ages) <= 60  # ATTITUDE at 25 Hz: a reading at most 40 ms old + transfer
    # Attitude in the replies matches the emulator's (roll/pitch are small in a hover: check yaw
    # is near 0 and roll/pitch magnitudes agree within 30 mrad).
    assert all(abs(rep.att_mrad[0]) < 200 and abs(rep.att_mrad[1]) < 200 for _, rep in with_att)
