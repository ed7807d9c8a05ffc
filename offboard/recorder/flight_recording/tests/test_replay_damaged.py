"""flight_recording.replay on recordings that are cut short or damaged: a clear warning naming the
damage, and the frames read up to it (a damaged chunk skipped, the frames after it kept). The
recording is written with the `mcap` library in quad-control's layout (topics and JSON fields of
docs/recording.md), small chunks so that a cut or a flipped byte hits one chunk of many."""

from __future__ import annotations

import base64
import json

import numpy as np
import pytest
from flight_recording import replay
from mcap.writer import CompressionType, Writer

FRAMES = 60
W, H = 8, 6
FR1_K = [517.3, 0.0, 318.6, 0.0, 516.5, 255.3, 0.0, 0.0, 1.0]


def _stamp(i: int) -> dict:
    t_ns = 1_000_000_000 + i * 33_333_333
    return {"sec": t_ns // 10**9, "nsec": t_ns % 10**9}


def write_recording(path) -> None:
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=4096, compression=CompressionType.NONE)
        w.start()
        schema = w.register_schema("json", "jsonschema", b"{}")
        ch = {
            topic: w.register_channel(topic, "json", schema)
            for topic in (
                "/camera/calibration",
                "/camera/rgb/compressed",
                "/camera/depth/compressed",
                "/slam/pose",
            )
        }

        def put(topic: str, i: int, data: dict) -> None:
            t = 1_000_000_000 + i * 33_333_333
            w.add_message(ch[topic], t, json.dumps(data).encode(), t)

        put("/camera/calibration", 0, {"K": FR1_K, "D": [0.0] * 5, "depth_units_per_m": 1000.0})
        for i in range(FRAMES):
            depth = np.full((H, W), 1000 + i, np.uint16).tobytes()
            put(
                "/camera/rgb/compressed",
                i,
                {
                    "timestamp": _stamp(i),
                    "data": base64.b64encode(b"\xff\xd8 frame %d" % i).decode(),
                },
            )
            put(
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
            put(
                "/slam/pose",
                i,
                {
                    "timestamp": _stamp(i),
                    "pose": {
                        "position": {"x": 0.01 * i, "y": 0.0, "z": 1.0},
                        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                    },
                },
            )
        w.finish()


@pytest.fixture
def recording(tmp_path):
    path = tmp_path / "flight.mcap"
    write_recording(path)
    return path


def _stamps(out) -> list[str]:
    return [
        line.split()[0]
        for line in (out / "tum" / "rgb.txt").read_text().splitlines()
        if not line.startswith("#")
    ]


def test_whole_recording_has_no_damage_and_every_frame(recording, tmp_path, capsys):
    assert replay.main([str(recording), "--out", str(tmp_path / "out"), "--extract-only"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["frames"] == FRAMES and result["damage"] is None and result["complete"]


def test_cut_recording_warns_and_replays_the_frames_before_the_cut(recording, tmp_path, capsys):
    # GIVEN a recording cut at 60 % of its bytes (quad-control killed)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[: int(recording.stat().st_size * 0.6)])
    # WHEN it is extracted for replay
    assert replay.main([str(cut), "--out", str(tmp_path / "out"), "--extract-only"]) == 0
    captured = capsys.readouterr()
    result = json.loads(captured.out)
    # THEN a warning names the cut and the frames replayed, which are the first ones, in order
    assert "WARNING" in captured.err and "incomplete" in captured.err
    assert "truncated at byte" in captured.err and f"the {result['frames']} frames" in captured.err
    assert 0 < result["frames"] < FRAMES
    whole = tmp_path / "whole"
    replay.extract(recording, whole)
    assert _stamps(tmp_path / "out") == _stamps(whole)[: result["frames"]]


def test_damaged_chunk_is_skipped_and_the_frames_after_it_are_kept(recording, tmp_path, capsys):
    # GIVEN a recording with bytes flipped in the middle (one chunk's CRC fails)
    data = bytearray(recording.read_bytes())
    middle = len(data) // 2
    for i in range(middle, middle + 64):
        data[i] ^= 0x5A
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    assert replay.main([str(bad), "--out", str(tmp_path / "out"), "--extract-only"]) == 0
    captured = capsys.readouterr()
    result = json.loads(captured.out)
    assert "WARNING" in captured.err and "skipped" in captured.err
    assert 0 < result["frames"] < FRAMES
    stamps = _stamps(tmp_path / "out")
    whole = tmp_path / "whole"
    replay.extract(recording, whole)
    all_stamps = _stamps(whole)
    # Frames on both sides of the damage: the last frame of the file is still there.
    assert stamps[0] == all_stamps[0] and stamps[-1] == all_stamps[-1]


def test_recording_cut_before_any_frame_is_refused_with_the_damage(recording, tmp_path, capsys):
    cut = tmp_path / "stub.mcap"
    cut.write_bytes(recording.read_bytes()[:40])
    assert replay.main([str(cut), "--out", str(tmp_path / "out"), "--extract-only"]) == 1
    err = capsys.readouterr().err
    assert "no /camera/calibration message" in err and "incomplete" in err


def test_missing_file_is_named(tmp_path, capsys):
    assert replay.main([str(tmp_path / "none.mcap"), "--out", str(tmp_path / "o")]) == 1
    assert "no such file" in capsys.readouterr().err
