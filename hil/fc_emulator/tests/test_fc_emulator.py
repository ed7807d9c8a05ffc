"""Flight-controller emulator: hover, step responses, arming, radio failsafe, ground contact,
MAVLink.

GIVEN/WHEN/THEN in each test; everything runs in simulated time (deterministic, seeded noise).
"""

import math

import numpy as np
import pytest
from fc_emulator import FcOptions, FlightControllerEmulator, FlightMode, QuadModel, QuadParams, fly
from fc_emulator.emulator import ARM_DELAY_US, FS_COUNTER, FS_THR_VALUE_US, LAND_SPEED_MPS
from fc_emulator.quad_model import GRAVITY_MSS
from fw_limits import FW_LIMITS
from pymavlink.dialects.v20 import common as mavlink2

ARM = [1500, 1500, 1000, 2000]  # throttle zero, yaw full right
MID = [1500, 1500, 1500, 1500]  # AltHold: hold altitude
CLIMB = [1500, 1500, 1800, 1500]
# The firmware's failsafe output: neutral sticks, kFailsafeThrottleUs (firmware/core/limits.h).
FS_LOW = [1500, 1500, FW_LIMITS["kFailsafeThrottleUs"], 1500]


def armed_and_hovering(altitude_m=1.7, **kw):
    fc = FlightControllerEmulator(**kw)
    fly(fc, ARM, 2.1)
    assert fc.armed
    while fc.snapshot().altitude_m < altitude_m:
        fly(fc, CLIMB, 0.02)
        assert fc.t_us < 20e6, "never reached the climb altitude"
    fly(fc, MID, 5.0)
    return fc


def test_model_hover_equilibrium_at_hover_output():
    # GIVEN a level craft in the air WHEN the motors give exactly the hover output THEN it stays put
    model = QuadModel(QuadParams())
    model.state.on_ground = False
    model.state.pos_ned_m[2] = -1.7
    model.state.motor_output = model.params.hover_output
    for _ in range(4000):  # 10 s at 400 Hz
        model.step(0.0025, 0.0, 0.0, 0.0, model.params.hover_output)
    assert abs(model.state.altitude_m - 1.7) < 1e-9
    assert np.allclose(model.state.vel_ned_mps, 0.0, atol=1e-9)
    # The accelerometer reads -1 g on body z at rest.
    assert np.allclose(model.specific_force_body_mss(), [0, 0, -GRAVITY_MSS], atol=1e-9)


def test_althold_mid_stick_holds_altitude():
    fc = armed_and_hovering(1.7)
    start = fc.snapshot()
    fly(fc, MID, 10.0)
    end = fc.snapshot()
    assert abs(end.altitude_m - start.altitude_m) < 0.02
    assert abs(end.climb_rate_mps) < 0.01
    assert end.motor_output == pytest.approx(0.5, abs=0.01)
    assert np.hypot(*end.pos_ned_m[:2]) < 1e-6  # level sticks: no horizontal drift


def test_althold_hover_survives_battery_sag():
    # GIVEN battery sag WHEN hovering 60 s THEN the z integrator compensates and voltage has dropped
    fc = armed_and_hovering(1.5, params=QuadParams(battery_sag=True))
    fly(fc, MID, 15.0)  # the z integrator needs ~20 s to learn the sagging thrust
    v0 = fc.snapshot().battery_v
    alt0 = fc.snapshot().altitude_m
    fly(fc, MID, 45.0)
    end = fc.snapshot()
    assert end.battery_v < v0 - 0.1
    assert end.altitude_m == pytest.approx(alt0, abs=0.03)
    assert end.motor_output > 0.5  # needs more output for the same thrust


@pytest.mark.parametrize("stick_us,expected_deg", [(1750, 21.6), (1250, -21.6), (2000, 45.0)])
def test_roll_step_response(stick_us, expected_deg):
    # 1750 us = (250-20)/(500-20) of ANGLE_MAX 45 deg = 21.56 deg
    fc = armed_and_hovering()
    fly(fc, [stick_us, 1500, 1500, 1500], 0.3)
    early = math.degrees(fc.snapshot().roll_rad)
    peak = early
    for _ in range(70):  # to 1.0 s after the step
        fly(fc, [stick_us, 1500, 1500, 1500], 0.01)
        peak = max(peak, math.degrees(fc.snapshot().roll_rad), key=abs)
    final = math.degrees(fc.snapshot().roll_rad)
    assert final == pytest.approx(expected_deg, abs=0.5)
    assert abs(early) > 0.6 * abs(expected_deg)  # 60 % of the step within 300 ms
    assert abs(peak) <= abs(expected_deg) * 1.10  # overshoot <= 10 %
    # Positive roll (right wing down) accelerates the craft east (+y in NED).
    assert np.sign(fc.snapshot().vel_ned_mps[1]) == np.sign(expected_deg)


def test_pitch_forward_moves_north_and_drag_limits_speed():
    fc = armed_and_hovering()
    fly(fc, [1500, 1250, 1500, 1500], 15.0)  # stick forward = low PWM = nose down
    s = fc.snapshot()
    assert s.pitch_rad < 0
    assert s.vel_ned_mps[0] > 2.0
    assert s.vel_ned_mps[0] < 10.0  # drag gives a terminal speed
    assert s.altitude_m == pytest.approx(1.7, abs=0.3)  # angle boost + z loop hold height


def test_yaw_rate_step():
    fc = armed_and_hovering()
    fly(fc, [1500, 1500, 1500, 1750], 1.0)
    rate = fc.model.state.rate_body_rad_s[2]
    assert math.degrees(rate) == pytest.approx(202.5 * 230 / 480, rel=0.02)


def test_althold_climb_rate_step():
    fc = armed_and_hovering()
    fly(fc, [1500, 1500, 2000, 1500], 2.0)
    assert fc.snapshot().climb_rate_mps == pytest.approx(2.5, abs=0.1)


def test_stabilize_mid_stick_gives_hover_output():
    fc = FlightControllerEmulator(options=FcOptions(mode=FlightMode.STABILIZE))
    fly(fc, ARM, 2.1)
    fly(fc, [1500, 1500, 1600, 1500], 1.0)
    assert fc.snapshot().altitude_m > 0.2
    fly(fc, MID, 1.0)
    assert fc.snapshot().motor_output == pytest.approx(0.5, abs=0.01)


def test_arming_needs_full_delay_and_low_throttle():
    fc = FlightControllerEmulator()
    fly(fc, ARM, (ARM_DELAY_US - 100_000) / 1e6)
    assert not fc.armed
    fly(fc, MID, 1.0)  # gesture interrupted: timer restarts
    fly(fc, ARM, 1.5)
    assert not fc.armed
    fly(fc, ARM, 0.6)
    assert fc.armed
    fc2 = FlightControllerEmulator()
    fly(fc2, [1500, 1500, 1200, 2000], 5.0)
    assert not fc2.armed


def test_disarm_gesture_on_ground():
    fc = FlightControllerEmulator()
    fly(fc, ARM, 2.1)
    fly(fc, [1500, 1500, 1000, 1000], 2.1)
    assert not fc.armed


def test_failsafe_throttle_lands_below_land_speed():
    fc = armed_and_hovering(1.7)
    fly(fc, FS_LOW, 0.1)
    s = fc.snapshot()
    assert s.radio_failsafe and s.mode == FlightMode.LAND
    fly(fc, FS_LOW, 10.0)
    assert not fc.armed
    assert fc.snapshot().altitude_m == 0.0
    assert len(fc.touchdowns_mps) == 1
    # LAND_SPEED 0.5 m/s; 1 cm/s margin for the velocity loop's residual error.
    assert 0.3 < fc.touchdowns_mps[0] <= LAND_SPEED_MPS + 0.01


def test_failsafe_on_rc_loss():
    fc = armed_and_hovering(1.0)
    fly(fc, None, 0.45)
    assert not fc.snapshot().radio_failsafe  # 500 ms timeout not reached
    fly(fc, None, 0.2)
    assert fc.snapshot().radio_failsafe and fc.mode == FlightMode.LAND
    fly(fc, None, 6.0)
    assert not fc.armed and fc.touchdowns_mps[0] <= LAND_SPEED_MPS + 0.01


def test_failsafe_while_landed_disarms_at_once():
    fc = FlightControllerEmulator()
    fly(fc, ARM, 2.1)
    fly(fc, FS_LOW, 0.1)
    assert not fc.armed and fc.snapshot().altitude_m == 0.0


def test_brief_low_throttle_glitch_does_not_trigger_failsafe():
    fc = armed_and_hovering(1.0)
    fly(fc, FS_LOW, 0.04)  # 2 RC frames < FS_COUNTER (3)
    fly(fc, MID, 1.0)
    assert not fc.snapshot().radio_failsafe and fc.mode == FlightMode.ALT_HOLD


def test_ground_contact_free_fall():
    # GIVEN a craft at 2 m with motors off WHEN it falls THEN it stops at the floor, never below
    model = QuadModel(QuadParams())
    model.state.on_ground = False
    model.state.pos_ned_m[2] = -2.0
    lowest = 0.0
    for _ in range(2000):
        model.step(0.0025, 0.0, 0.0, 0.0, 0.0)
        lowest = min(lowest, model.state.altitude_m)
    assert lowest == 0.0 and model.state.on_ground
    v_ff = math.sqrt(2 * GRAVITY_MSS * 2.0)  # drag makes it a bit slower than free fall
    assert 0.8 * v_ff < model.touchdowns_mps[0] < v_ff


def test_disarmed_craft_stays_on_ground():
    fc = FlightControllerEmulator()
    fly(fc, [1500, 1500, 2000, 1500], 3.0)  # full throttle but never armed
    s = fc.snapshot()
    assert not s.armed and s.altitude_m == 0.0 and s.motor_output == 0.0


def test_invalid_pulses_are_rejected():
    fc = FlightControllerEmulator()
    assert not fc.feed_pulse(2, 850, 1000)
    assert not fc.feed_pulse(2, float("nan"), 1000)
    assert not fc.feed_pulse(2, 2300, 1000)
    assert fc.feed_pulse(2, 1100, 1000)
    assert fc.rc.rejected_count == 3
    with pytest.raises(ValueError):
        fc.feed_pulse(4, 1500, 1000)
    with pytest.raises(ValueError):
        fc.feed_rc([1500, 1500], 1000)


@pytest.mark.parametrize(
    "bad",
    [
        dict(attitude_hz=0),
        dict(raw_imu_hz=-1.0),
        dict(mode=FlightMode.LAND),
        dict(accel_noise_mg=float("nan")),
    ],
)
def test_options_validation(bad):
    with pytest.raises(ValueError):
        FlightControllerEmulator(options=FcOptions(**bad))


def test_params_validation():
    with pytest.raises(ValueError, match="mass_kg"):
        QuadModel(QuadParams(mass_kg=0.0))
    with pytest.raises(ValueError, match="hover_output"):
        QuadModel(QuadParams(hover_output=1.0))


def test_mavlink_v2_bytes_decode_at_configured_rates():
    frames = []
    fc = FlightControllerEmulator(
        sink=lambda t, d: frames.append((t, d)),
        options=FcOptions(attitude_hz=25.0, raw_imu_hz=10.0, seed=7),
    )
    fly(fc, ARM, 2.1)
    fly(fc, CLIMB, 1.0)
    fly(fc, [1700, 1500, 1500, 1500], 6.9)  # 10 s in all, leaning right for the last 6.9 s
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = False
    counts = {}
    last_att = None
    last_hb = None
    for t_us, data in frames:
        assert data[0] == 0xFD  # MAVLink v2 start byte
        msgs = parser.parse_buffer(data)
        assert msgs is not None and len(msgs) == 1
        m = msgs[0]
        counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
        if m.get_type() == "ATTITUDE":
            assert m.time_boot_ms == t_us // 1000
            last_att = m
        if m.get_type() == "HEARTBEAT":
            last_hb = m
    assert counts["HEARTBEAT"] == pytest.approx(10, abs=1)
    assert counts["ATTITUDE"] == pytest.approx(250, abs=2)
    assert counts["RAW_IMU"] == pytest.approx(100, abs=2)
    assert last_att.roll == pytest.approx(fc.snapshot().roll_rad, abs=0.05)
    assert last_att.roll > 0.2
    assert last_hb.type == mavlink2.MAV_TYPE_QUADROTOR
    assert last_hb.autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert last_hb.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    assert last_hb.custom_mode == int(FlightMode.ALT_HOLD)


def test_raw_imu_reads_gravity_and_is_seeded():
    def run(seed):
        out = []
        parser = mavlink2.MAVLink(None)

        def sink(_t, d):
            for m in parser.parse_buffer(d) or []:
                if m.get_type() == "RAW_IMU":
                    out.append((m.xacc, m.yacc, m.zacc))

        fc = FlightControllerEmulator(sink=sink, options=FcOptions(seed=seed))
        fly(fc, [1500, 1500, 1000, 1500], 3.0)
        return np.array(out)

    a, b, c = run(3), run(3), run(4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.mean(a[:, 2]) == pytest.approx(-1000, abs=5)  # -1 g on body z, in mg
    assert np.std(a[:, 0]) == pytest.approx(8, rel=0.4)


def test_gusts_are_seeded_with_the_configured_strength():
    def gusts(seed):
        m = QuadModel(QuadParams(gust_accel_std_mss=0.3, gust_tau_s=2.0, disturbance_seed=seed))
        out = []
        for _ in range(40000):  # 100 s
            m.step(0.0025, 0.0, 0.0, 0.0, 0.0)
            out.append(m.gust_mss[0])
        return np.array(out)

    a, b, c = gusts(1), gusts(1), gusts(2)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.std(a) == pytest.approx(0.3, rel=0.35)  # 100 s is ~50 correlation times


def test_trim_error_makes_a_craft_drift_under_level_sticks():
    fc = armed_and_hovering(1.0, params=QuadParams(trim_error_deg=(1.0, 0.0)))
    fly(fc, MID, 5.0)
    s = fc.snapshot()
    assert math.degrees(s.roll_rad) == pytest.approx(1.0, abs=0.1)
    assert s.vel_ned_mps[1] > 0.1  # drifting east (right)


def test_gusts_push_a_hovering_craft_around():
    fc = armed_and_hovering(1.0, params=QuadParams(gust_accel_std_mss=0.3))
    alt0 = fc.snapshot().altitude_m
    fly(fc, MID, 10.0)
    assert np.hypot(*fc.snapshot().pos_ned_m[:2]) > 0.05
    assert fc.snapshot().altitude_m == pytest.approx(alt0, abs=0.05)  # gusts are horizontal


def test_emulated_apm_parameters_are_the_ones_the_firmware_assumes():
    # The firmware's hand-over to the APM's radio failsafe (limits.h kApmFsThrValueUs,
    # kApmFsCounterFrames) is designed against ArduCopter's FS_THR_VALUE and FS_COUNTER; the
    # emulated APM must use the same values or the HIL failsafe scenarios test another hand-over.
    assert FS_THR_VALUE_US == FW_LIMITS["kApmFsThrValueUs"]
    assert FS_COUNTER == FW_LIMITS["kApmFsCounterFrames"]
