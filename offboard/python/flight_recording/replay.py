r"""Replays a quad-control MCAP recording through SLAM and compares with the poses recorded in
flight.

    PYTHONPATH=offboard/python:protocol/python python -m flight_recording.replay FLIGHT.mcap \
        --out DIR [--slam-eval BIN] [--tum-score BIN]

  1. extracts the recorded frames into a TUM RGB-D folder DIR/tum: rgb/<t>.jpg (the recorded JPEG
     bytes, not re-encoded), depth/<t>.png (16-bit, decoded from /camera/depth/compressed - RVL or
     zstd-delta, flight_recording.depth - or, in older recordings, /camera/depth/raw; rescaled to
     the TUM convention of 5000 units per metre from the recording's depth_units_per_m), rgb.txt,
     depth.txt, and groundtruth.txt = the
     poses quad-control used in flight (/slam/pose, T_floor_cam at each frame's capture time);
  2. writes DIR/flight.tum (the same in-flight poses, for evo: `evo_ape tum DIR/flight.tum
     DIR/slam/trajectory.tum -a`);
  3. runs `slam-eval run` on the folder (ORB + local map, deterministic "wait" mode) and scores its
     trajectory against the in-flight poses with tum-score (rigid alignment: the replay's world is
     its first camera, the flight's is the floor frame; 20 ms association).
Prints one JSON object (frames, poses, ATE of replay vs flight) and writes it to DIR/replay.json.
A recording cut short (quad-control killed, disk full) or with a damaged chunk is replayed up to the
damage (a damaged chunk is skipped, the frames after it are kept): a warning on stderr says where
the file is damaged and how many frames are replayed, and the JSON carries it as `damage`.
The camera is recognised from the recorded calibration (slam-eval knows the TUM cameras); a
recording with other intrinsics is refused with the reason.
"""

from __future__ import annotations

import argparse
import base64
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from rgbd_protocol.tum_cameras import TUM_CAMERAS as _TUM_MODELS
from rgbd_protocol.tum_cameras import TUM_DEPTH_UNITS_PER_M

from flight_recording.depth import decode as decode_depth
from flight_recording.reader import read

ROOT = Path(__file__).resolve().parents[3]
# The Freiburg cameras slam-eval's --camera accepts (slam::Intrinsics::from_name), fx fy cx cy;
# one definition: protocol/camera/tum_cameras.json. TUM_DEPTH_UNITS_PER_M is its depth scale.
TUM_CAMERAS = {
    name: (c.fx_px, c.fy_px, c.cx_px, c.cy_px)
    for name, c in _TUM_MODELS.items()
    if name.startswith("fr")
}
INTRINSICS_TOLERANCE_PX = 0.05


def camera_name(K: list[float]) -> str:
    fx, fy, cx, cy = K[0], K[4], K[2], K[5]
    for name, ref in TUM_CAMERAS.items():
        if all(
            abs(a - b) <= INTRINSICS_TOLERANCE_PX
            for a, b in zip((fx, fy, cx, cy), ref, strict=False)
        ):
            return name
    raise ValueError(
        f"recorded intrinsics fx {fx} fy {fy} cx {cx} cy {cy} are not a TUM camera slam-eval knows"
    )


def stamp_s(header: dict) -> float:
    return header["sec"] + header["nsec"] * 1e-9


def extract(mcap: Path, out: Path) -> dict:
    """Writes the TUM folder and flight.tum; returns what was extracted."""
    from PIL import Image

    rec = read(mcap)
    rgb = {
        m.data["timestamp"]["sec"] * 10**9 + m.data["timestamp"]["nsec"]: m.data
        for m in rec.topic("/camera/rgb/compressed")
    }
    # Every recorded frame's depth as the link carried it; older recordings: the 16UC1 channel.
    depth_topic = (
        "/camera/depth/compressed" if rec.topic("/camera/depth/compressed") else "/camera/depth/raw"
    )
    depth = {
        m.data["timestamp"]["sec"] * 10**9 + m.data["timestamp"]["nsec"]: m.data
        for m in rec.topic(depth_topic)
    }
    cal = rec.topic("/camera/calibration")
    if not cal:
        damage = damage_summary(mcap, rec, 0)
        raise ValueError(
            f"{mcap}: no /camera/calibration message "
            f"({damage if damage else 'recorded without images?'})"
        )
    calib = cal[0].data
    units = float(calib.get("depth_units_per_m", TUM_DEPTH_UNITS_PER_M))
    tum = out / "tum"
    (tum / "rgb").mkdir(parents=True, exist_ok=True)
    (tum / "depth").mkdir(parents=True, exist_ok=True)
    stamps = sorted(set(rgb) & set(depth))
    rgb_lines, depth_lines = [], []
    for t_ns in stamps:
        t = f"{t_ns * 1e-9:.6f}"
        (tum / "rgb" / f"{t}.jpg").write_bytes(base64.b64decode(rgb[t_ns]["data"]))
        d = depth[t_ns]
        encoding = d.get("encoding") if depth_topic == "/camera/depth/compressed" else "raw"
        raw = decode_depth(encoding, base64.b64decode(d["data"]), d["width"], d["height"])
        units = float(d.get("depth_units_per_m", units))
        scaled = np.clip(
            np.rint(raw.astype(np.float64) * (TUM_DEPTH_UNITS_PER_M / units)), 0, 65535
        ).astype(np.uint16)
        buf = io.BytesIO()
        Image.fromarray(scaled).save(buf, format="PNG")
        (tum / "depth" / f"{t}.png").write_bytes(buf.getvalue())
        rgb_lines.append(f"{t} rgb/{t}.jpg")
        depth_lines.append(f"{t} depth/{t}.png")
    header = "# extracted from {} by flight_recording.replay\n# timestamp filename\n".format(
        mcap.name
    )
    (tum / "rgb.txt").write_text(header + "\n".join(rgb_lines) + "\n")
    (tum / "depth.txt").write_text(header + "\n".join(depth_lines) + "\n")
    poses = []
    for m in rec.topic("/slam/pose"):
        p = m.data["pose"]
        pos, q = p["position"], p["orientation"]
        poses.append(
            f"{stamp_s(m.data['timestamp']):.6f} {pos['x']:.6f} {pos['y']:.6f} {pos['z']:.6f} "
            f"{q['x']:.9f} {q['y']:.9f} {q['z']:.9f} {q['w']:.9f}"
        )
    traj = (
        "# quad-control in-flight poses T_floor_cam (from {})\n".format(mcap.name)
        + "\n".join(poses)
        + "\n"
    )
    (out / "flight.tum").write_text(traj)
    (tum / "groundtruth.txt").write_text(traj)
    D = calib.get("D", [])
    return {
        "frames": len(stamps),
        "flight_poses": len(poses),
        "camera": camera_name(calib["K"]),
        "distortion": any(abs(x) > 0 for x in D),
        "errors": rec.errors,
        "complete": rec.complete,
        "damage": damage_summary(mcap, rec, len(stamps)),
    }


def damage_summary(mcap: Path, rec, frames: int) -> str | None:
    """One sentence on what is wrong with a recording that is not whole, or None if it is."""
    if rec.complete and not rec.errors:
        return None
    size = mcap.stat().st_size
    # The reader's own findings, without its note that the seeking read failed (always the case
    # for such a file; the streaming read's errors say why).
    found = [e for e in rec.errors if not e.startswith("seeking read failed")]
    if not rec.complete and not found:
        found = [f"no footer: the file ends after its last whole record at byte {rec.bytes_read}"]
    return (
        f"{mcap.name} is {'damaged' if rec.complete else 'incomplete'} ({size} bytes, "
        f"{rec.bytes_read} usable): {'; '.join(found)}; replaying the {frames} frames read "
        "(a damaged chunk's frames are missing, a cut file ends at its last whole chunk)"
    )


def _warn_damage(info: dict) -> None:
    if info.get("damage"):
        print(f"flight_recording.replay: WARNING: {info['damage']}", file=sys.stderr)


def run(mcap: Path, out: Path, slam_eval: Path, tum_score: Path) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    info = extract(mcap, out)
    _warn_damage(info)
    if info["frames"] < 2 or info["flight_poses"] < 2:
        raise ValueError(
            f"{mcap}: {info['frames']} frames and {info['flight_poses']} poses: nothing to replay"
        )
    cmd = [
        str(slam_eval),
        "run",
        "--dataset",
        str(out / "tum"),
        "--out",
        str(out / "slam"),
        "--camera",
        info["camera"],
        "--mode",
        "wait",
        "--no-map",
        "--quiet",
    ]
    if not info["distortion"]:
        cmd.append(
            "--no-undistort"
        )  # the recorded camera has no distortion (e.g. the HIL renderer)
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    score = subprocess.run(
        [str(tum_score), str(out / "flight.tum"), str(out / "slam" / "trajectory.tum")],
        check=True,
        capture_output=True,
        text=True,
    )
    s = json.loads(score.stdout)
    result = dict(
        info,
        replay_poses=sum(
            1
            for line in (out / "slam" / "trajectory.tum").read_text().splitlines()
            if line and not line.startswith("#")
        ),
        ate_replay_vs_flight_rmse_m=s["ate_rmse_m"],
        ate_replay_vs_flight_max_m=s["ate_max_m"],
        ate_rot_rmse_deg=s.get("ate_rot_rmse_deg"),
        pairs=s["pairs"],
        command=" ".join(cmd),
    )
    (out / "replay.json").write_text(json.dumps(result, indent=2))
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("recording", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--slam-eval", type=Path, default=ROOT / "build" / "bin" / "slam-eval")
    ap.add_argument("--tum-score", type=Path, default=ROOT / "build" / "bin" / "tum-score")
    ap.add_argument(
        "--extract-only",
        action="store_true",
        help="write the TUM folder and flight.tum, run nothing",
    )
    a = ap.parse_args(argv)
    if not a.recording.is_file():
        print(f"flight_recording.replay: {a.recording}: no such file", file=sys.stderr)
        return 1
    try:
        if a.extract_only:
            result = extract(a.recording, a.out)
            _warn_damage(result)
        else:
            result = run(a.recording, a.out, a.slam_eval, a.tum_score)
    except (ValueError, subprocess.CalledProcessError) as e:
        detail = getattr(e, "stderr", "") or ""
        print(f"flight_recording.replay: {e}\n{detail}", file=sys.stderr)
        return 1
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
