"""Scoring helpers of the closed-loop flights: frames (truth camera vs quad-control's floor frame),
hold error, and the sequence number that ties a firmware request to the flight log."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hilrig.flight import CameraMount
from hilrig.slam_flight import _seq_of, camera_room_position, goal_in_room, hold_error


@dataclass
class Snap:
    t_us: int
    pos_ned_m: tuple
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0


def test_camera_on_the_ground_at_take_off_is_the_mount_offset_in_the_room():
    # Body centre 20 cm above the floor at (-1.5, 0.5); camera 10 cm ahead (north), 5 cm below.
    p = camera_room_position(Snap(0, (0.0, 0.0, 0.0)), CameraMount())
    assert p == pytest.approx([-1.4, 0.5, 0.15])
    # 1 m north, 1 m east and 1.5 m up in NED: room x north, y west, z up.
    p = camera_room_position(Snap(0, (1.0, 1.0, -1.5)), CameraMount())
    assert p == pytest.approx([-0.4, -0.5, 1.65])


def test_floor_frame_goal_is_a_translation_by_the_start_position():
    start = np.array([-1.4, 0.5, 0.15])
    assert goal_in_room(start, (1.0, 0.8, 1.7)) == pytest.approx([-0.4, 1.3, 1.7])


def test_hold_error_uses_only_the_window_and_splits_the_axes():
    mount = CameraMount()
    start = camera_room_position(Snap(0, (0.0, 0.0, 0.0)), mount)
    goal = goal_in_room(start, (0.0, 0.0, 1.7))
    # Body at 1.75 m above the floor puts the camera at 1.70 m: on the goal; then 0.1 m north.
    hist = [
        Snap(0, (5.0, 0.0, -1.55)),
        Snap(1_000_000, (0.0, 0.0, -1.55)),
        Snap(2_000_000, (0.1, 0.0, -1.55)),
    ]
    e = hold_error(hist, goal, mount, 1_000_000, 2_000_000)
    assert e["samples"] == 2
    assert e["max_horizontal_m"] == pytest.approx(0.1, abs=1e-3)
    assert e["max_vertical_m"] == pytest.approx(0.0, abs=1e-3)
    assert hold_error(hist, goal, mount, 3e6, 4e6) == {"samples": 0}


def test_sequence_number_of_a_request_line():
    assert _seq_of("PUT /control?seq=42&arm=1&roll=1500&pitch=1500&thr=1000&yaw=1500&mac=00") == 42
    assert _seq_of("GET /status") is None


def test_slam_tracking_counts_every_map_of_every_slam_server_run(tmp_path):
    from types import SimpleNamespace

    from hilrig.slam_flight import SlamFlight

    header = "index,state,keyframe,relocalised,attitude_predicted,cross_checked,frontend_cpu_ms\n"
    first = tmp_path / "slam-tables" / "map-1"
    first.mkdir(parents=True)
    (first / "frames.csv").write_text(
        header + "0,tracking,1,0,0,0,5\n1,tracking,0,0,1,1,9\n2,lost,0,0,1,0,7\n"
    )
    restarted = tmp_path / "slam-tables-1" / "map-1"
    restarted.mkdir(parents=True)
    (restarted / "frames.csv").write_text(header + "0,tracking,0,1,1,1,11\n")
    out = SlamFlight.slam_tracking(SimpleNamespace(workdir=tmp_path))
    assert out == {
        "frames": 4,
        "lost": 1,
        "relocalised": 1,
        "cross_checked": 2,
        "attitude_predicted": 3,
        "keyframes": 1,
        "tracking_cpu_ms": {"median": 8.0, "p95": 10.7},
    }
    assert SlamFlight.slam_tracking(SimpleNamespace(workdir=tmp_path / "none")) == {"frames": 0}
