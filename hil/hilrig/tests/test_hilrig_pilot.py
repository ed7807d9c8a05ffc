"""The ground-truth pilot and flight recorder (fast, no processes): the reference the closed-loop
scenarios with SLAM in the loop are compared against."""

import numpy as np
import pytest
from fc_emulator import FlightControllerEmulator
from hilrig.flight import Leg, arm, fly_plan, hold_error_m
from hilrig.pilot import _angle_to_stick, _climb_to_throttle, sticks_for
from kinect_emulator import KinectEmulator, KinectOptions, default_room, load_textures


def test_stick_mappings_invert_arducopter():
    assert _angle_to_stick(0.0) == 1500
    assert _angle_to_stick(np.radians(45)) == 2000 and _angle_to_stick(-np.radians(90)) == 1000
    assert _climb_to_throttle(0.0) == 1500
    assert _climb_to_throttle(2.5) == 2000 and _climb_to_throttle(-2.5) == 1000
    assert 1600 < _climb_to_throttle(0.3) < 1700


def test_takeoff_and_hold_1p7m_with_ground_truth_feedback():
    # Scenario 1 with a perfect position source: the bound the SLAM-in-the-loop version is held to.
    fc = FlightControllerEmulator()
    arm(fc)
    t0 = fc.t_us
    log = fly_plan(fc, [Leg((0.0, 0.0, -1.7), 0.0, 40.0)])
    settle_us = t0 + 10_000_000
    err = hold_error_m(log, settle_us, fc.t_us)
    assert err["max_m"] < 0.15, err
    assert fc.snapshot().altitude_m == pytest.approx(1.7, abs=0.05)


def test_waypoints_reached():
    fc = FlightControllerEmulator()
    arm(fc)
    fly_plan(fc, [Leg((0.0, 0.0, -1.5), 0.0, 6.0), Leg((1.5, 1.0, -1.5), 0.5, 10.0)])
    s = fc.snapshot()
    assert np.allclose(s.pos_ned_m, (1.5, 1.0, -1.5), atol=0.1)
    assert s.yaw_rad == pytest.approx(0.5, abs=0.05)


def test_pilot_points_sticks_the_right_way():
    fc = FlightControllerEmulator()
    s = fc.snapshot()
    roll, pitch, thr, yaw = sticks_for(s, (1.0, 1.0, -1.0), 0.3)
    assert pitch < 1500 and roll > 1500 and thr > 1500 and yaw > 1500  # N, E, up, yaw right


def test_recording_renders_frames_at_sensor_rate():
    room = default_room(load_textures(max_count=4))
    kin = KinectEmulator(room, KinectOptions(fps=10.0))
    fc = FlightControllerEmulator()
    arm(fc)
    frames = []
    log = fly_plan(fc, [Leg((0.0, 0.0, -1.0), 0.0, 1.0)], kinect=kin, sink=frames.append)
    assert log.frames == len(frames) == 10
    assert all(
        b.capture_us - a.capture_us == 100000 for a, b in zip(frames, frames[1:], strict=False)
    )
