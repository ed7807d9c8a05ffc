"""A stand-in for the engine's `slam-eval run` with the same command line and outputs, for tests
of the sweep (the real binary is built by another component and may be absent).

Its trajectory is the ground truth at every k-th colour frame with seeded noise that grows with the
per-frame motion (so binned errors have a trend to find). Environment switches:
  FAKE_SLAM_EVAL_FAIL=<features>  exit 3 for that detector (a failing configuration)
  FAKE_SLAM_EVAL_LOG=<file>       append one line per invocation (to count runs; --no-undistort
                                  is written at its end when given)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import zlib
from pathlib import Path

import numpy as np

from slam_study import se3, tum

# Noise model: 1 mm + 20 % of the per-frame translation, 0.05 deg + 10 % of the rotation (per axis).
kBaseNoiseMm = 1.0
kTransNoiseFraction = 0.2
kBaseNoiseDeg = 0.05
kRotNoiseFraction = 0.1


def main() -> int:
    parser = argparse.ArgumentParser(prog="fake-slam-eval")
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run")
    run.add_argument("--dataset", required=True)
    run.add_argument("--features", default="orb")
    run.add_argument("--backend", default="vo")
    run.add_argument("--rate", type=int, default=1)
    run.add_argument("--mode", default="wait")
    run.add_argument("--out", required=True)
    for flag in ("--no-undistort", "--no-map", "--quiet"):  # the study's --slam-eval-args
        run.add_argument(flag, action="store_true")
    args = parser.parse_args()
    if os.environ.get("FAKE_SLAM_EVAL_LOG"):
        with open(os.environ["FAKE_SLAM_EVAL_LOG"], "a") as fh:
            undistort = " --no-undistort" if args.no_undistort else ""
            fh.write(f"{args.dataset} {args.features} {args.backend} {args.rate}{undistort}\n")
    if os.environ.get("FAKE_SLAM_EVAL_FAIL") == args.features:
        print(f"fake-slam-eval: {args.features} is configured to fail", file=sys.stderr)
        return 3
    ds = tum.Dataset.load(args.dataset)
    gt = ds.groundtruth_at_frames(args.rate)
    seed = zlib.crc32(f"{args.features}-{args.backend}-{args.rate}".encode())
    rng = np.random.default_rng(seed)
    poses = [gt.poses[0]]
    for i in range(1, len(gt)):
        rel = se3.relative(gt.poses[i - 1], gt.poses[i])
        t_mm = 1000 * np.linalg.norm(rel[:3, 3])
        r_deg = float(se3.rotation_angle_deg(rel[:3, :3]))
        noise = np.eye(4)
        noise[:3, 3] = rng.normal(0, (kBaseNoiseMm + kTransNoiseFraction * t_mm) / 1000, 3)
        angle = np.radians(rng.normal(0, kBaseNoiseDeg + kRotNoiseFraction * r_deg, 3))
        noise[:3, :3] = se3.quat_xyzw_to_rot(np.append(np.sin(angle / 2), 1.0))
        poses.append(poses[-1] @ rel @ noise)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tum.write_trajectory(out / "trajectory.tum", tum.Trajectory(gt.stamps_s, np.array(poses)))
    metrics = {
        "frames": len(gt),
        "keyframes": max(1, len(gt) // 3),
        "loop_closures": 0,
        "timing": {
            "extract": {"mean_ms": 10.0, "median_ms": 9.5, "p95_ms": 14.0},
            "match": {"mean_ms": 2.0, "median_ms": 1.9, "p95_ms": 3.0},
        },
    }
    (out / "metrics.json").write_text(json.dumps(metrics))
    print(f"fake-slam-eval: {len(gt)} frames", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
