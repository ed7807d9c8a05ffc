"""hil/tools/rerender_flight.py: a live flight's delivered frames, made again as a TUM folder."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

TOOL = Path(__file__).resolve().parents[1] / "rerender_flight.py"
sys.path.insert(0, str(TOOL.parent))
import rerender_flight  # noqa: E402
from kinect_emulator.poses import camera_pose_from_ned  # noqa: E402
from kinect_emulator.renderer import KinectEmulator, KinectOptions  # noqa: E402
from kinect_emulator.room import default_room  # noqa: E402
from slam_study.se3 import quat_xyzw_to_rot  # noqa: E402

ORIGIN_ROOM_M = (-1.5, 0.5, 0.2)  # the HIL flights' take-off point


def _flight(tmp_path: Path, n: int = 3) -> tuple[Path, list[dict]]:
    """A flight folder whose Kinect delivered n frames (render indices 5, 7, 8, ...: a skipped
    render in between) while the craft climbed and yawed, plus one frame never delivered."""
    lines = []
    for k in range(n):
        T = camera_pose_from_ned(
            np.array([0.1 * k, 0.0, -1.0 - 0.05 * k]),
            0.02,
            -0.03,
            0.2 * k,
            origin_room_m=ORIGIN_ROOM_M,
        )
        t = 100.0 + k / 30
        lines.append(
            {
                "index": 5 + k + (k > 0),
                "seq": k,
                "t_mono_s": t,
                "T_room_cam": T.ravel().tolist(),
                "superseded": 0,
                "render_start_mono_s": t,
                "render_end_mono_s": t + 0.008,
                "delivered": True,
                "index_written_mono_s": t + 0.009,
                "depth_file": f"d-{k}.pgm",
                "rgb_file": f"r-{k}.ppm",
            }
        )
    dump = tmp_path / "flight" / "kinect-dump"
    dump.mkdir(parents=True)
    skipped = dict(lines[0], index=6, delivered=False, t_mono_s=100.01)
    text = "\n".join(json.dumps(d) for d in (*lines, skipped))
    (dump / "live_frames.jsonl").write_text(text + "\n")
    return dump.parent, lines


def _listed(out: Path, name: str) -> list[list[str]]:
    return [ln.split() for ln in (out / name).read_text().splitlines() if not ln.startswith("#")]


def test_the_delivered_frames_are_made_again_as_the_streamer_read_them(tmp_path):
    # GIVEN a flight whose Kinect delivered three frames
    flight, recs = _flight(tmp_path)
    out = tmp_path / "tum"
    # WHEN they are re-rendered
    assert rerender_flight.main([str(flight), "--out", str(out)]) == 0
    # THEN each frame is the live emulator's frame of that render index, bit for bit, its depth as
    # rgbd-streamer read it back from 11-bit disparity, at 5000 units per metre
    emu = KinectEmulator(default_room(), KinectOptions(seed=rerender_flight.FLIGHT_KINECT_SEED))
    lut = rerender_flight.live_depth_lut()
    rgb = _listed(out, "rgb.txt")
    assert [s for s, _ in rgb] == [f"{r['t_mono_s']:.6f}" for r in recs]
    for (stamp, _), r in zip(rgb, recs, strict=True):
        T = np.array(r["T_room_cam"]).reshape(4, 4)
        frame = emu.render_indexed(T, int(round(r["t_mono_s"] * 1e6)), r["index"])
        assert np.array_equal(np.asarray(Image.open(out / "rgb" / f"{stamp}.png")), frame.rgb)
        depth = np.asarray(Image.open(out / "depth" / f"{stamp}.png")).astype(np.int64)
        assert np.array_equal(depth, lut[frame.depth_mm].astype(np.int64) * 5)
    # AND the round trip changes depth (the emulator's mm are not what the streamer reads)
    assert not np.array_equal(lut[frame.depth_mm], frame.depth_mm)
    # AND the ground truth is each frame's pose, the attitude its rotation in NED (room = NWU)
    gt = _listed(out, "groundtruth.txt")
    att = _listed(out, "attitude.txt")
    for g, a, r in zip(gt, att, recs, strict=True):
        T = np.array(r["T_room_cam"]).reshape(4, 4)
        assert np.allclose([float(x) for x in g[1:4]], T[:3, 3], atol=1e-6)
        R = quat_xyzw_to_rot(np.array([float(x) for x in a[1:5]]))
        assert np.allclose(R, np.diag([1.0, -1.0, -1.0]) @ T[:3, :3], atol=1e-9)


def test_the_flights_own_attitude_goes_to_the_frames_it_was_given_with(tmp_path):
    # GIVEN the attitude quad-control gave SLAM, stamped with capture times after the INDEX write,
    # for the first and third frames only
    flight, recs = _flight(tmp_path)
    att = tmp_path / "attitude.txt"
    att.write_text(
        "# camera attitude (NED) given to SLAM in flight\n# timestamp qx qy qz qw\n"
        f"{recs[0]['index_written_mono_s'] + 0.001:.6f} 0.1 0.2 0.3 0.9\n"
        f"{recs[2]['index_written_mono_s'] + 0.002:.6f} 0.4 0.5 0.6 0.7\n"
    )
    out = tmp_path / "tum"
    assert rerender_flight.main([str(flight), "--out", str(out), "--attitude", str(att)]) == 0
    # THEN those frames carry it at their exposure stamps, and the second carries none
    assert _listed(out, "attitude.txt") == [
        [f"{recs[0]['t_mono_s']:.6f}", "0.1", "0.2", "0.3", "0.9"],
        [f"{recs[2]['t_mono_s']:.6f}", "0.4", "0.5", "0.6", "0.7"],
    ]


@pytest.mark.parametrize(
    "setup, message",
    [
        ("no_records", "cannot read the flight's records"),
        ("bad_attitude", "expected 'timestamp qx qy qz qw'"),
        ("not_empty", "exists and is not empty"),
        ("bad_seconds", "--seconds must be > 0"),
    ],
)
def test_bad_input_is_refused_with_a_message(tmp_path, capsys, setup, message):
    flight, _ = _flight(tmp_path, n=1)
    out = tmp_path / "tum"
    args = [str(flight), "--out", str(out)]
    if setup == "no_records":
        args[0] = str(tmp_path / "elsewhere")
    elif setup == "bad_attitude":
        (tmp_path / "att.txt").write_text("100.0 0.1 0.2 0.3\n")
        args += ["--attitude", str(tmp_path / "att.txt")]
    elif setup == "not_empty":
        out.mkdir()
        (out / "x").write_text("x")
    else:
        args += ["--seconds", "nan"]
    assert rerender_flight.main(args) == 2
    assert message in capsys.readouterr().err
