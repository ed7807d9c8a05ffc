#!/usr/bin/env python3
"""Re-renders the frames a live HIL flight's Kinect delivered as a TUM RGB-D folder for `slam-eval`.

The live Kinect emulator renders frame number `index` as a pure function of the room, its options
and the pose (KinectEmulator.render_indexed), and its records file (`kinect-dump/live_frames.jsonl`
in a flight's folder) keeps every delivered frame's index, exposure time and pose. So the images
slam-server was given can be made again bit for bit, at any time after the flight, and the
flight's first minutes replayed through SLAM deterministically in seconds instead of re-flown in
minutes: an estimate that drifts in one flight can then be taken apart frame by frame.

The folder has rgb/ and depth/ (PNG; depth at 5000 units per metre, after the live path's
libfreenect round trip: 11-bit disparity and back, as rgbd-streamer's FreenectSource reads it),
rgb.txt and depth.txt stamped with each frame's exposure time (CLOCK_MONOTONIC s), groundtruth.txt
(T_room_cam, TUM format) and attitude.txt (the camera's attitude in NED, which slam-eval gives SLAM
with each frame as quad-control does in flight): the rendered camera's own attitude, or with
--attitude the one quad-control gave SLAM in flight (the attitude.txt `flight_recording.replay`
extracts from the flight's recording, stamped with capture times; frames it has no line for get
none).

  hil/tools/rerender_flight.py FLIGHT_DIR --out DIR [--seconds 90] [--attitude FILE] [--seed 11]
  build/bin/slam-eval run --dataset DIR --out RUN --camera fr1 --no-undistort --rolling-shutter off

Exit 0 on success; 2 with a message on bad options, a folder without the records file, or an
unwritable output folder.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

_ROOT = Path(__file__).resolve().parents[2]
for _sub in ("hil", "hil/tools", "protocol/python"):
    sys.path.insert(0, str(_ROOT / _sub))

from hilrig.slam_flight import SlamFlightOptions  # noqa: E402
from kinect_emulator.live import RECORDS_NAME, delivered_record, match_capture_stamps  # noqa: E402
from kinect_emulator.poses import R_NWU_NED, rotation_to_quaternion_xyzw  # noqa: E402
from kinect_emulator.renderer import KinectEmulator, KinectOptions  # noqa: E402
from kinect_emulator.room import default_room  # noqa: E402
from kinect_emulator.writers import (  # noqa: E402
    TUM_DEPTH_UNITS_PER_M,
    depth_mm_to_freenect_raw,
    freenect_raw_to_depth_mm,
)
from render_tum import prepare_tum_folder, write_png16, write_png_rgb  # noqa: E402

# The noise seed the HIL flights' Kinect renders with (the rig's default).
FLIGHT_KINECT_SEED = SlamFlightOptions.kinect_seed


def live_depth_lut() -> np.ndarray:
    """mm -> mm as the live path delivers it: the emulator writes 11-bit disparity
    (depth_mm_to_freenect_raw), rgbd-streamer's FreenectSource reads it back to mm."""
    return freenect_raw_to_depth_mm(depth_mm_to_freenect_raw(np.arange(1 << 16, dtype=np.uint16)))


def read_records(flight_dir: Path, seconds: float) -> list:
    """The delivered frames of the flight's first `seconds` (exposure time from the first)."""
    path = flight_dir / "kinect-dump" / RECORDS_NAME
    recs = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                d = json.loads(line)
            except json.JSONDecodeError as e:  # a flight killed mid-write leaves a partial line
                print(f"rerender_flight: {path}:{n}: skipped ({e})", file=sys.stderr)
                continue
            if d.get("delivered"):
                recs.append(delivered_record(d))
    recs.sort(key=lambda r: r.t_mono_s)
    if not recs:
        return []
    return [r for r in recs if r.t_mono_s - recs[0].t_mono_s <= seconds]


def flight_attitudes(path: Path, recs: list) -> dict[int, str]:
    """render index -> 'qx qy qz qw' of the attitude quad-control gave SLAM with that frame."""
    stamps, quats = [], []
    for line in path.read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        v = line.split()
        if len(v) != 5:
            raise ValueError(f"{path}: expected 'timestamp qx qy qz qw', got {line!r}")
        stamps.append(float(v[0]) * 1e6)
        quats.append(" ".join(v[1:]))
    matched = match_capture_stamps(recs, stamps)
    return {r.index: q for r, q in zip(matched, quats, strict=True) if r is not None}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("flight_dir", help="a live flight's folder (with kinect-dump/live_frames.jsonl)")
    p.add_argument("--out", required=True, help="folder to write (created; must be empty)")
    p.add_argument("--seconds", type=float, default=90.0, help="from the first frame")
    p.add_argument("--attitude", help="the flight's attitude.txt (flight_recording.replay)")
    p.add_argument("--seed", type=int, default=FLIGHT_KINECT_SEED, help="the Kinect's noise seed")
    args = p.parse_args(argv)
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        print(f"rerender_flight: --seconds must be > 0, got {args.seconds}", file=sys.stderr)
        return 2
    flight = Path(args.flight_dir)
    try:
        recs = read_records(flight, args.seconds)
    except OSError as e:
        print(f"rerender_flight: cannot read the flight's records: {e}", file=sys.stderr)
        return 2
    if not recs:
        print(f"rerender_flight: {flight} has no delivered frame", file=sys.stderr)
        return 2
    attitudes = None
    if args.attitude:
        try:
            attitudes = flight_attitudes(Path(args.attitude), recs)
        except (OSError, ValueError) as e:
            print(f"rerender_flight: --attitude: {e}", file=sys.stderr)
            return 2
    out = Path(args.out)
    problem = prepare_tum_folder(out)
    if problem:
        print(f"rerender_flight: {problem}", file=sys.stderr)
        return 2
    emulator = KinectEmulator(default_room(), KinectOptions(seed=args.seed))
    lut = live_depth_lut()
    rgb_lines, depth_lines, gt_lines, att_lines = [], [], [], []
    for k, r in enumerate(recs):
        frame = emulator.render_indexed(r.T_room_cam, int(round(r.t_mono_s * 1e6)), r.index)
        stamp = f"{r.t_mono_s:.6f}"
        write_png_rgb(out / "rgb" / f"{stamp}.png", frame.rgb)
        depth = lut[frame.depth_mm].astype(np.uint32) * TUM_DEPTH_UNITS_PER_M // 1000
        write_png16(out / "depth" / f"{stamp}.png", depth)
        rgb_lines.append(f"{stamp} rgb/{stamp}.png")
        depth_lines.append(f"{stamp} depth/{stamp}.png")
        R = r.T_room_cam[:3, :3]
        q = " ".join(f"{c:.8f}" for c in rotation_to_quaternion_xyzw(R))
        tx, ty, tz = r.T_room_cam[:3, 3]
        gt_lines.append(f"{stamp} {tx:.6f} {ty:.6f} {tz:.6f} {q}")
        if attitudes is None:  # the room is NWU: R_ned_cam = R_NED_NWU R_room_cam
            q_ned = rotation_to_quaternion_xyzw(R_NWU_NED.T @ R)
            att_lines.append(f"{stamp} " + " ".join(repr(float(c)) for c in q_ned))
        elif r.index in attitudes:
            att_lines.append(f"{stamp} {attitudes[r.index]}")
        if k % 300 == 0:
            print(f"rerender_flight: frame {k}/{len(recs)}", file=sys.stderr)
    header = "# re-rendered by hil/tools/rerender_flight.py from " + str(flight)
    (out / "rgb.txt").write_text(header + "\n" + "\n".join(rgb_lines) + "\n")
    (out / "depth.txt").write_text(header + "\n" + "\n".join(depth_lines) + "\n")
    (out / "groundtruth.txt").write_text(
        header + "\n# timestamp tx ty tz qx qy qz qw\n" + "\n".join(gt_lines) + "\n"
    )
    source = "the flight's " + args.attitude if attitudes is not None else "the rendered camera"
    att_header = f"# camera attitude (NED), {source}\n# timestamp qx qy qz qw\n"
    (out / "attitude.txt").write_text(att_header + "\n".join(att_lines) + "\n")
    print(f"rerender_flight: {len(recs)} frames in {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
