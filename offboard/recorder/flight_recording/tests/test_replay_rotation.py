"""flight_recording.replay on a rotated recording (quad-control starts NAME-001.mcap past
max_file_mb): every file in order, a frame whose colour ends one file and whose depth starts the
next kept, and only the frames the flight's SLAM answered (/slam/tracking) listed."""

from __future__ import annotations

import base64
import json

import numpy as np
import pytest
from flight_recording import replay
from mcap.writer import CompressionType, Writer

W, H = 8, 6
FR1_K = [517.3, 0.0, 318.6, 0.0, 516.5, 255.3, 0.0, 0.0, 1.0]
FRAMES = 30
SPLIT = 17  # frame 17's colour goes in the first file, its depth in the second
NOT_ANSWERED = {5, 21}  # frames slam-server never got in flight
# A unit quaternion whose components need 17 digits to read back as the same doubles.
_Q = np.array([0.1, -0.3, 0.5, 0.8]) / np.linalg.norm([0.1, -0.3, 0.5, 0.8])
Q_NED_CAM = {k: float(v) for k, v in zip("xyzw", _Q, strict=True)}


def _t_ns(i: int) -> int:
    return 2_000_000_000 + i * 33_333_000


def _stamp(i: int) -> dict:
    return {"sec": _t_ns(i) // 10**9, "nsec": _t_ns(i) % 10**9}


def _write(path, messages) -> None:
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=4096, compression=CompressionType.NONE)
        w.start()
        schema = w.register_schema("json", "jsonschema", b"{}")
        ch = {}
        for topic, i, data in messages:
            if topic not in ch:
                ch[topic] = w.register_channel(topic, "json", schema)
            w.add_message(ch[topic], _t_ns(i), json.dumps(data).encode(), _t_ns(i))
        w.finish()


def _frame_messages(i: int) -> list:
    depth = np.full((H, W), 1000 + i, np.uint16).tobytes()
    rgb = (
        "/camera/rgb/compressed",
        i,
        {"timestamp": _stamp(i), "data": base64.b64encode(b"\xff\xd8 %d" % i).decode()},
    )
    dep = (
        "/camera/depth/compressed",
        i,
        {
            "timestamp": _stamp(i),
            "encoding": "raw",
            "width": W,
            "height": H,
            "depth_units_per_m": 1000.0,
            "data": base64.b64encode(depth).decode(),
        },
    )
    out = [rgb, dep]
    if i not in NOT_ANSWERED:
        tracking = {"capture_us": _t_ns(i) // 1000, "tracking": True}
        if i % 2 == 0:  # the attitude given to SLAM with the frame, when the APM sent one
            tracking["q_ned_cam"] = dict(Q_NED_CAM)
        out.append(("/slam/tracking", i, tracking))
        pose = {
            "position": {"x": 0.01 * i, "y": 0.0, "z": 1.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        }
        out.append(("/slam/pose", i, {"timestamp": _stamp(i), "pose": pose}))
    return out


@pytest.fixture
def rotation(tmp_path):
    first, second = [], []
    cal = ("/camera/calibration", 0, {"K": FR1_K, "D": [0.0] * 5, "depth_units_per_m": 1000.0})
    first.append(cal)
    for i in range(FRAMES):
        msgs = _frame_messages(i)
        if i < SPLIT:
            first += msgs
        elif i == SPLIT:
            first.append(msgs[0])
            second += msgs[1:]
        else:
            second += msgs
    _write(tmp_path / "flight-20261206-054521-000.mcap", first)
    _write(tmp_path / "flight-20261206-054521-001.mcap", second)
    # Another recording in the same folder is not part of the rotation.
    _write(tmp_path / "flight-20261206-060000-000.mcap", [cal])
    return tmp_path


def _listed(out) -> list[str]:
    lines = (out / "tum" / "rgb.txt").read_text().splitlines()
    return [line.split()[0] for line in lines if not line.startswith("#")]


def test_rotation_files_are_the_recordings_files_in_order(rotation):
    files = replay.rotation_files(rotation / "flight-20261206-054521-000.mcap")
    assert [f.name for f in files] == [
        "flight-20261206-054521-000.mcap",
        "flight-20261206-054521-001.mcap",
    ]
    other = rotation / "flight-20261206-060000-000.mcap"
    assert replay.rotation_files(other) == [other]


def test_whole_rotation_is_extracted_with_the_frames_slam_answered(rotation, tmp_path, capsys):
    # GIVEN the first file of a two-file recording
    first = rotation / "flight-20261206-054521-000.mcap"
    # WHEN it is extracted
    assert replay.main([str(first), "--out", str(tmp_path / "out"), "--extract-only"]) == 0
    result = json.loads(capsys.readouterr().out)
    # THEN both files are read, the frame split across them is kept, the unanswered ones are not
    assert len(result["files"]) == 2
    assert result["frames_recorded"] == FRAMES
    assert result["frames"] == FRAMES - len(NOT_ANSWERED)
    assert result["flight_poses"] == FRAMES - len(NOT_ANSWERED)
    listed = _listed(tmp_path / "out")
    assert f"{_t_ns(SPLIT) * 1e-9:.6f}" in listed
    assert all(f"{_t_ns(i) * 1e-9:.6f}" not in listed for i in NOT_ANSWERED)
    assert listed == sorted(listed)
    assert len(list((tmp_path / "out" / "tum" / "rgb").iterdir())) == len(listed)


def test_the_attitude_given_to_slam_goes_to_attitude_txt(rotation, tmp_path, capsys):
    # GIVEN a recording whose even frames carried an attitude to SLAM
    first = rotation / "flight-20261206-054521-000.mcap"
    # WHEN it is extracted
    assert replay.main([str(first), "--out", str(tmp_path / "out"), "--extract-only"]) == 0
    result = json.loads(capsys.readouterr().out)
    # THEN attitude.txt lists exactly the replayed frames that carried one, with its value
    lines = (tmp_path / "out" / "tum" / "attitude.txt").read_text().splitlines()
    rows = [line.split() for line in lines if not line.startswith("#")]
    expected = [i for i in range(FRAMES) if i % 2 == 0 and i not in NOT_ANSWERED]
    assert [r[0] for r in rows] == [f"{_t_ns(i) * 1e-9:.6f}" for i in expected]
    # bit for bit: the replay's SLAM must get the flight's attitude exactly
    assert all([float(x) for x in r[1:]] == [Q_NED_CAM[k] for k in "xyzw"] for r in rows)
    assert result["frames_with_attitude"] == len(expected)


def test_single_file_and_all_frames(rotation, tmp_path, capsys):
    first = rotation / "flight-20261206-054521-000.mcap"
    args = [str(first), "--out", str(tmp_path / "one"), "--extract-only", "--single-file"]
    assert replay.main([*args, "--frames", "all"]) == 0
    result = json.loads(capsys.readouterr().out)
    # Frame SPLIT has no depth in the first file: it cannot be paired.
    assert len(result["files"]) == 1 and result["frames"] == SPLIT


def test_folder_without_recordings_is_refused(tmp_path, capsys):
    assert replay.main([str(tmp_path), "--out", str(tmp_path / "o")]) == 1
    assert "no .mcap file" in capsys.readouterr().err
