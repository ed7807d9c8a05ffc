r"""Replays a quad-control MCAP recording through SLAM and compares with the poses recorded in
flight.

    PYTHONPATH=offboard/recorder:protocol/python python -m flight_recording.replay FLIGHT.mcap \
        --out DIR [--slam-eval BIN] [--tum-score BIN]

  1. extracts the recorded frames into a TUM RGB-D folder DIR/tum: rgb/<t>.jpg (the recorded JPEG
     bytes, not re-encoded), depth/<t>.png (16-bit, decoded from /camera/depth/compressed - RVL or
     zstd-delta, flight_recording.depth - or, in older recordings, /camera/depth/raw; rescaled to
     the TUM convention of 5000 units per metre from the recording's depth_units_per_m), rgb.txt,
     depth.txt, attitude.txt = the camera attitude each frame carried to SLAM in flight
     (/slam/tracking q_ned_cam: the rotation prior and gravity direction; recordings made before
     it was recorded have none), and groundtruth.txt = the
     poses quad-control used in flight (/slam/pose, T_floor_cam at each frame's capture time);
  2. writes DIR/flight.tum (the same in-flight poses, for evo: `evo_ape tum DIR/flight.tum
     DIR/slam/trajectory.tum -a`);
  3. runs `slam-eval run` on the folder (ORB + local map, deterministic "wait" mode) and scores its
     trajectory against the in-flight poses with tum-score (rigid alignment: the replay's world is
     its first camera, the flight's is the floor frame; 20 ms association). With --lock-schedule
     (the lock_schedule.txt slam-server wrote beside the flight map's frames.csv) it runs in live
     mode held to the flight's order of tracking, mapping and loop closing instead
     (slam/core/lock_schedule.hpp), which reproduces the mapper's progress as it was in flight.
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
import glob
import io
import json
import re
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
PNG_COMPRESS_LEVEL = 1


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


ROTATED_NAME = re.compile(r"^(?P<stem>.+)-(?P<index>\d{3})\.mcap$")


def rotation_files(mcap: Path) -> list[Path]:
    """Every file of the rotated recording `mcap` belongs to, in recording order. quad-control
    starts a new file past `recording.max_file_mb` (flight-<date>-<time>-000.mcap, -001, ...); a
    file not named so is a recording of its own."""
    m = ROTATED_NAME.match(mcap.name)
    if not m:
        return [mcap]
    siblings = []
    for f in mcap.parent.glob(f"{glob.escape(m['stem'])}-*.mcap"):
        s = ROTATED_NAME.match(f.name)
        if s and s["stem"] == m["stem"]:
            siblings.append((int(s["index"]), f))
    return [f for _, f in sorted(siblings)] or [mcap]


def _stamp_ns(data: dict) -> int:
    return data["timestamp"]["sec"] * 10**9 + data["timestamp"]["nsec"]


def extract(mcap: Path | list[Path], out: Path, frames: str = "slam") -> dict:
    """Writes the TUM folder and flight.tum from one file or the files of a rotated recording (in
    the order given); returns what was extracted. frames: "slam" lists the frames the flight's SLAM
    answered (/slam/tracking; every recorded frame when the recording has no such channel), "all"
    every recorded frame. Files are read one at a time, so memory holds one file's messages."""
    from PIL import Image

    files = [mcap] if isinstance(mcap, Path) else list(mcap)
    tum = out / "tum"
    (tum / "rgb").mkdir(parents=True, exist_ok=True)
    (tum / "depth").mkdir(parents=True, exist_ok=True)
    calib = None
    rgb_wait: dict[int, dict] = {}  # a frame's colour or depth may end one file, the other the next
    depth_wait: dict[int, tuple[str, dict]] = {}
    written: list[int] = []
    answered: set[int] = set()
    attitude: dict[int, dict] = {}  # capture stamp (ns) -> q_ned_cam given to SLAM with the frame
    has_tracking = False
    poses = []
    errors: list[str] = []
    damage: list[str] = []
    complete = True
    for f in files:
        written_before = len(written)
        rec = read(f)
        errors += [f"{f.name}: {e}" for e in rec.errors]
        complete = complete and rec.complete
        cal = rec.topic("/camera/calibration")
        if calib is None and cal:
            calib = cal[0].data
        for m in rec.topic("/camera/rgb/compressed"):
            rgb_wait[_stamp_ns(m.data)] = m.data
        # Every recorded frame's depth as the link carried it; older recordings: the 16UC1 channel.
        compressed = rec.topic("/camera/depth/compressed")
        for m in compressed or rec.topic("/camera/depth/raw"):
            depth_wait[_stamp_ns(m.data)] = ("compressed" if compressed else "raw", m.data)
        tracking = rec.topic("/slam/tracking")
        has_tracking = has_tracking or bool(tracking)
        answered.update(int(m.data["capture_us"]) * 1000 for m in tracking)
        attitude.update(
            (int(m.data["capture_us"]) * 1000, m.data["q_ned_cam"])
            for m in tracking
            if "q_ned_cam" in m.data
        )
        for m in rec.topic("/slam/pose"):
            p = m.data["pose"]
            pos, q = p["position"], p["orientation"]
            poses.append(
                f"{stamp_s(m.data['timestamp']):.6f} {pos['x']:.6f} {pos['y']:.6f} {pos['z']:.6f} "
                f"{q['x']:.9f} {q['y']:.9f} {q['z']:.9f} {q['w']:.9f}"
            )
        if calib is None:
            summary = damage_summary(f, rec, 0)
            if summary:
                damage.append(summary)
            continue  # no image can be scaled yet (a calibration comes with every preview)
        default_units = float(calib.get("depth_units_per_m", TUM_DEPTH_UNITS_PER_M))
        for t_ns in sorted(set(rgb_wait) & set(depth_wait)):
            t = f"{t_ns * 1e-9:.6f}"
            (tum / "rgb" / f"{t}.jpg").write_bytes(base64.b64decode(rgb_wait.pop(t_ns)["data"]))
            kind, d = depth_wait.pop(t_ns)
            encoding = d.get("encoding") if kind == "compressed" else "raw"
            raw = decode_depth(encoding, base64.b64decode(d["data"]), d["width"], d["height"])
            units = float(d.get("depth_units_per_m", default_units))
            scaled = np.clip(
                np.rint(raw.astype(np.float64) * (TUM_DEPTH_UNITS_PER_M / units)), 0, 65535
            ).astype(np.uint16)
            buf = io.BytesIO()
            # zlib level 1: lossless like any level, 3x faster than Pillow's default 6 on these
            # frames (34 vs 108 ms each on a loaded machine), 25 % larger files.
            Image.fromarray(scaled).save(buf, format="PNG", compress_level=PNG_COMPRESS_LEVEL)
            (tum / "depth" / f"{t}.png").write_bytes(buf.getvalue())
            written.append(t_ns)
        summary = damage_summary(f, rec, len(written) - written_before)
        if summary:
            damage.append(summary)
        del rec
    if calib is None:
        names = ", ".join(f.name for f in files)
        raise ValueError(
            f"{names}: no /camera/calibration message "
            f"({'; '.join(damage) if damage else 'recorded without images?'})"
        )
    # The frames slam-server was given in flight: the others were dropped on the way (the SLAM
    # link's one-frame mailbox keeps the newest while slam-server is busy, a link stall, a
    # restart). Replaying them would give the replay's map keyframes the flight never had.
    chosen = [t for t in written if t in answered] if frames == "slam" and has_tracking else written
    for t_ns in set(written) - set(chosen):
        t = f"{t_ns * 1e-9:.6f}"
        (tum / "rgb" / f"{t}.jpg").unlink()
        (tum / "depth" / f"{t}.png").unlink()
    names = ", ".join(f.name for f in files)
    header = f"# extracted from {names} by flight_recording.replay\n# timestamp filename\n"
    stamps = [f"{t * 1e-9:.6f}" for t in sorted(chosen)]
    (tum / "rgb.txt").write_text(header + "".join(f"{t} rgb/{t}.jpg\n" for t in stamps))
    (tum / "depth.txt").write_text(header + "".join(f"{t} depth/{t}.png\n" for t in stamps))
    # The attitude each frame carried to SLAM in flight (rotation prior, gravity): slam-eval reads
    # attitude.txt so that the replay's SLAM gets the same inputs as the flight's.
    with_attitude = [t for t in sorted(chosen) if t in attitude]
    if with_attitude:
        lines = "".join(
            # repr: the shortest text that reads back as the same double, so slam-eval gets the
            # flight's attitude bit for bit (a lock-step replay reproduces the flight's poses).
            f"{t * 1e-9:.6f} {attitude[t]['x']!r} {attitude[t]['y']!r} "
            f"{attitude[t]['z']!r} {attitude[t]['w']!r}\n"
            for t in with_attitude
        )
        (tum / "attitude.txt").write_text(
            f"# camera attitude (NED) given to SLAM in flight, from {names}\n"
            f"# timestamp qx qy qz qw\n{lines}"
        )
    traj = f"# quad-control in-flight poses T_floor_cam (from {names})\n" + "\n".join(poses) + "\n"
    (out / "flight.tum").write_text(traj)
    (tum / "groundtruth.txt").write_text(traj)
    D = calib.get("D", [])
    return {
        "files": [str(f) for f in files],
        "frames": len(chosen),
        "frames_recorded": len(written),
        "frames_not_given_to_slam_in_flight": len(written) - len(chosen),
        "frame_selection": "slam" if frames == "slam" and has_tracking else "all",
        "frames_with_attitude": len(with_attitude),
        "flight_poses": len(poses),
        "camera": camera_name(calib["K"]),
        "distortion": any(abs(x) > 0 for x in D),
        "errors": errors,
        "complete": complete,
        "damage": "; ".join(damage) if damage else None,
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


def _score(tum_score: Path, flight: Path, replay: Path) -> dict:
    score = subprocess.run(
        [str(tum_score), str(flight), str(replay)], check=True, capture_output=True, text=True
    )
    return json.loads(score.stdout)


def run(
    mcap: Path | list[Path],
    out: Path,
    slam_eval: Path,
    tum_score: Path,
    frames: str = "slam",
    lock_schedule: Path | None = None,
) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    info = extract(mcap, out, frames)
    _warn_damage(info)
    if info["frames"] < 2 or info["flight_poses"] < 2:
        raise ValueError(
            f"{', '.join(info['files'])}: {info['frames']} frames and "
            f"{info['flight_poses']} poses: nothing to replay"
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
        # The SLAM link carries no rolling-shutter readout: slam-server and quad-control track
        # every frame as a global shutter, and the replay must do as they did.
        "--rolling-shutter",
        "off",
        "--no-map",
        "--quiet",
    ]
    if lock_schedule is None:
        cmd += ["--mode", "wait"]
    else:
        cmd += ["--mode", "live", "--replay-lock-schedule", str(lock_schedule)]
    if not info["distortion"]:
        cmd.append(
            "--no-undistort"
        )  # the recorded camera has no distortion (e.g. the HIL renderer)
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    # The poses flown are each frame's pose as tracked at the time; the replay's counterpart is
    # trajectory_online.tum. trajectory.tum re-anchors every frame to its keyframe as optimised
    # later by local bundle adjustment, which the flight never had: scored too, for reference.
    online = _score(tum_score, out / "flight.tum", out / "slam" / "trajectory_online.tum")
    final = _score(tum_score, out / "flight.tum", out / "slam" / "trajectory.tum")
    result = dict(
        info,
        replay_poses=sum(
            1
            for line in (out / "slam" / "trajectory_online.tum").read_text().splitlines()
            if line and not line.startswith("#")
        ),
        ate_replay_vs_flight_rmse_m=online["ate_rmse_m"],
        ate_replay_vs_flight_max_m=online["ate_max_m"],
        ate_rot_rmse_deg=online.get("ate_rot_rmse_deg"),
        pairs=online["pairs"],
        ate_final_trajectory_vs_flight_rmse_m=final["ate_rmse_m"],
        lock_schedule=json.loads((out / "slam" / "metrics.json").read_text()).get("lock_schedule"),
        command=" ".join(cmd),
    )
    (out / "replay.json").write_text(json.dumps(result, indent=2))
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "recording",
        type=Path,
        nargs="+",
        help="an MCAP file (a file of a rotated recording, NAME-NNN.mcap, brings the rotation's "
        "other files, in order), several files (read in the order given), or a folder (its .mcap "
        "files in name order)",
    )
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--slam-eval", type=Path, default=ROOT / "build" / "bin" / "slam-eval")
    ap.add_argument("--tum-score", type=Path, default=ROOT / "build" / "bin" / "tum-score")
    ap.add_argument(
        "--single-file",
        action="store_true",
        help="read only the file named, not the rest of its rotation",
    )
    ap.add_argument(
        "--frames",
        choices=("slam", "all"),
        default="slam",
        help="slam (default): the frames the flight's SLAM was given (/slam/tracking); all: every "
        "recorded frame",
    )
    ap.add_argument(
        "--lock-schedule",
        type=Path,
        help="slam-server's lock_schedule.txt of the flight's map (beside its frames.csv): replay "
        "in lock-step with the flight's tracking and mapping instead of wait mode",
    )
    ap.add_argument(
        "--extract-only",
        action="store_true",
        help="write the TUM folder and flight.tum, run nothing",
    )
    a = ap.parse_args(argv)
    files: list[Path] = []
    for r in a.recording:
        if r.is_dir():
            found = sorted(r.glob("*.mcap"))
            if not found:
                print(f"flight_recording.replay: {r}: no .mcap file in it", file=sys.stderr)
                return 1
            files += found
        elif not r.is_file():
            print(f"flight_recording.replay: {r}: no such file", file=sys.stderr)
            return 1
        elif len(a.recording) == 1 and not a.single_file:
            files += rotation_files(r)
        else:
            files.append(r)
    if a.lock_schedule is not None and not a.lock_schedule.is_file():
        print(f"flight_recording.replay: {a.lock_schedule}: no such file", file=sys.stderr)
        return 1
    if a.lock_schedule is not None and a.frames != "slam":
        print(
            "flight_recording.replay: --lock-schedule replays the frames the flight's SLAM was "
            "given: it needs --frames slam",
            file=sys.stderr,
        )
        return 1
    try:
        if a.extract_only:
            result = extract(files, a.out, a.frames)
            _warn_damage(result)
        else:
            result = run(files, a.out, a.slam_eval, a.tum_score, a.frames, a.lock_schedule)
    except (ValueError, subprocess.CalledProcessError) as e:
        detail = getattr(e, "stderr", "") or ""
        print(f"flight_recording.replay: {e}\n{detail}", file=sys.stderr)
        return 1
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
