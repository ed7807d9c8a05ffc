#!/usr/bin/env python3
"""Renders a craft manoeuvre in the HIL room as a TUM RGB-D folder, for `slam-eval`.

The Kinect emulator (hil/kinect_emulator: exact ray casting in the textured box room, the Kinect
v1's depth noise, quantisation, shadows and dropouts) renders the camera of a craft that flies
one of these manoeuvres at a hover height, with the camera mounted as in the HIL flights:

  turn    turns in place by --turn-deg at --yaw-rate-deg-s, ramping the rate up and down over
          --ramp-s (a craft's yaw authority is finite: no step in rate)
  dash    flies --dash-m straight ahead at --speed-m-s, ramped the same way, and back
  both    the turn, then the dash

The folder has rgb/, depth/ (16-bit PNG, 5000 units per metre), rgb.txt, depth.txt (same stamps:
one camera renders both) and groundtruth.txt (T_room_cam, TUM format: tx ty tz qx qy qz qw).
The renderer has no motion blur and no rolling shutter, so these frames isolate the geometry of
fast motion (prediction, search window, keyframes) from the image degradation of a real camera.

  hil/tools/render_tum.py --out DIR [--manoeuvre turn|dash|both] [--yaw-rate-deg-s 60] ...

Exit 0 on success; 2 with a message on bad options or an unwritable folder.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

_ROOT = Path(__file__).resolve().parents[2]
for _sub in ("hil", "protocol/python"):  # the emulator and the camera models it renders with
    sys.path.insert(0, str(_ROOT / _sub))

from kinect_emulator.poses import camera_pose_from_ned, rotation_to_quaternion_xyzw  # noqa: E402
from kinect_emulator.renderer import KinectEmulator, KinectOptions  # noqa: E402
from kinect_emulator.room import default_room  # noqa: E402

# The HIL flights' take-off point in the room (hil/hilrig/flight.py) and a hover height that
# keeps the 30 deg-down camera's view on walls and floor.
ORIGIN_ROOM_M = (-1.5, 0.5, 0.2)
HOVER_HEIGHT_M = 1.2
DEPTH_UNITS_PER_M = 5000  # TUM depth PNG scale (protocol/camera/tum_cameras.json)


def ramped_profile(total: float, peak_rate: float, ramp_s: float, dt: float) -> list[float]:
    """Cumulative progress (0 -> total) at steps of dt for a rate that ramps linearly from 0 to
    peak_rate over ramp_s, holds, and ramps down to 0 on arrival."""
    if total <= 0 or peak_rate <= 0:
        return [0.0]
    ramp_s = max(ramp_s, 1e-9)
    accel = peak_rate / ramp_s
    ramp_dist = 0.5 * peak_rate * ramp_s
    if 2 * ramp_dist > total:  # never reaches peak_rate: a triangle profile
        peak_rate = math.sqrt(total * accel)
        ramp_s = peak_rate / accel
        ramp_dist = total / 2
    cruise_s = (total - 2 * ramp_dist) / peak_rate
    duration = 2 * ramp_s + cruise_s
    out = []
    n = int(math.ceil(duration / dt))
    for i in range(n + 1):
        t = min(i * dt, duration)
        if t < ramp_s:
            s = 0.5 * accel * t * t
        elif t < ramp_s + cruise_s:
            s = ramp_dist + peak_rate * (t - ramp_s)
        else:
            u = duration - t
            s = total - 0.5 * accel * u * u
        out.append(s)
    return out


def manoeuvre_states(args) -> list[tuple[np.ndarray, float]]:
    """(position NED relative to take-off, yaw rad) per frame."""
    dt = 1.0 / args.fps
    hover = np.array([0.0, 0.0, -HOVER_HEIGHT_M])
    states: list[tuple[np.ndarray, float]] = [(hover, 0.0)] * int(args.settle_s * args.fps)
    yaw = 0.0
    if args.manoeuvre in ("turn", "both"):
        for s in ramped_profile(
            math.radians(args.turn_deg), math.radians(args.yaw_rate_deg_s), args.ramp_s, dt
        ):
            states.append((hover, s))
        yaw = math.radians(args.turn_deg)
        states += [(hover, yaw)] * int(args.settle_s * args.fps)
    if args.manoeuvre in ("dash", "both"):
        heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        out = ramped_profile(args.dash_m, args.speed_m_s, args.ramp_s, dt)
        for s in out:
            states.append((hover + heading * s, yaw))
        end = hover + heading * args.dash_m
        states += [(end, yaw)] * int(args.settle_s * args.fps)
        for s in out:
            states.append((end - heading * s, yaw))
        states += [(hover, yaw)] * int(args.settle_s * args.fps)
    return states


def prepare_tum_folder(out: Path) -> str | None:
    """Creates `out` with rgb/ and depth/; why not when it is not empty or cannot be made."""
    if out.exists() and any(out.iterdir()):
        return f"{out} exists and is not empty"
    try:
        (out / "rgb").mkdir(parents=True, exist_ok=True)
        (out / "depth").mkdir(exist_ok=True)
    except OSError as e:
        return f"cannot create {out}: {e}"
    return None


def write_png16(path: Path, depth_units: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(depth_units.astype(np.uint16)).save(path)


def write_png_rgb(path: Path, rgb: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(rgb).save(path)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True, help="folder to write (created; must be empty)")
    p.add_argument("--manoeuvre", choices=("turn", "dash", "both"), default="both")
    p.add_argument("--yaw-rate-deg-s", type=float, default=60.0, help="peak yaw rate")
    p.add_argument("--turn-deg", type=float, default=360.0, help="turn angle (ccw seen from above)")
    p.add_argument("--speed-m-s", type=float, default=1.0, help="peak dash speed")
    p.add_argument("--dash-m", type=float, default=2.0, help="dash length, out and back")
    p.add_argument("--ramp-s", type=float, default=0.5, help="time to reach the peak rate")
    p.add_argument("--settle-s", type=float, default=0.5, help="hover before and after each part")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--seed", type=int, default=1, help="the emulator's noise seed")
    args = p.parse_args(argv)
    for name in ("yaw_rate_deg_s", "speed_m_s", "dash_m", "ramp_s", "fps"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            print(f"render_tum: --{name.replace('_', '-')} must be > 0, got {v}", file=sys.stderr)
            return 2
    if not (math.isfinite(args.turn_deg) and math.isfinite(args.settle_s) and args.settle_s >= 0):
        print("render_tum: --turn-deg must be finite and --settle-s >= 0", file=sys.stderr)
        return 2
    out = Path(args.out)
    problem = prepare_tum_folder(out)
    if problem:
        print(f"render_tum: {problem}", file=sys.stderr)
        return 2
    emulator = KinectEmulator(default_room(), KinectOptions(fps=args.fps, seed=args.seed))
    states = manoeuvre_states(args)
    period_us = int(round(1e6 / args.fps))
    t0_s = 1000.0  # stamps well away from 0, like a sensor clock
    rgb_lines, depth_lines, gt_lines = [], [], []
    for i, (pos_ned, yaw) in enumerate(states):
        T = camera_pose_from_ned(pos_ned, 0.0, 0.0, yaw, origin_room_m=ORIGIN_ROOM_M)
        frame = emulator.render_indexed(T, i * period_us, i)
        stamp = f"{t0_s + i * period_us * 1e-6:.6f}"
        write_png_rgb(out / "rgb" / f"{stamp}.png", frame.rgb)
        depth = frame.depth_mm.astype(np.uint32) * DEPTH_UNITS_PER_M // 1000
        write_png16(out / "depth" / f"{stamp}.png", depth)
        rgb_lines.append(f"{stamp} rgb/{stamp}.png")
        depth_lines.append(f"{stamp} depth/{stamp}.png")
        qx, qy, qz, qw = rotation_to_quaternion_xyzw(T[:3, :3])
        tx, ty, tz = T[:3, 3]
        gt_lines.append(f"{stamp} {tx:.6f} {ty:.6f} {tz:.6f} {qx:.8f} {qy:.8f} {qz:.8f} {qw:.8f}")
        if i % 30 == 0:
            print(f"render_tum: frame {i}/{len(states)}", file=sys.stderr)
    header = "# rendered by hil/tools/render_tum.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    (out / "rgb.txt").write_text(header + "\n" + "\n".join(rgb_lines) + "\n")
    (out / "depth.txt").write_text(header + "\n" + "\n".join(depth_lines) + "\n")
    (out / "groundtruth.txt").write_text(
        header + "\n# timestamp tx ty tz qx qy qz qw\n" + "\n".join(gt_lines) + "\n"
    )
    print(f"render_tum: {len(states)} frames in {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
