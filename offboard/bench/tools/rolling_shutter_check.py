#!/usr/bin/env python3
"""Measures a camera's rolling-shutter readout time from a SLAM run and motion-capture ground truth.

    rolling_shutter_check.py --gt groundtruth.txt --frames RUN/frames.csv [--readout-s R]

The local-map tracker fits each frame's pose with the camera's angular velocity over the readout
as three more unknowns (docs/slam.md, Rolling shutter): the rows of a frame taken while the camera
turns are skewed by omega x readout, and the fit reads omega from that skew *for the readout it
assumes*. If the true readout is r and the run assumed R, the rows' rate is the true rate times
r / R. Regressing the rows' rate (frames.csv rolling_shutter_rate_x/y/z) on the motion capture's
rate at each frame therefore gives r = R x slope - a measurement of the sensor, not a fit of any
trajectory error. The mocap rate is the rotation between the ground truth at (stamp - h) and
(stamp + h), h half a frame interval, in the camera frame.

Run slam-eval with a wide rate prior so that the rate is the rows' alone:

    slam-eval run --dataset DIR --out RUN --rolling-shutter-readout-s 0.03 \\
        --rolling-shutter-angular-accel 100000

Noise in the rows' rate does not bias the slope (it is the regressed variable); the mocap rate is
nearly noise-free. A sequence that turns faster gives the better-conditioned figure. Exit status 1
with a message on unusable input.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from slam_study import se3, tum

# Half a frame interval at 30 fps: the mocap rate is taken over the frame's own interval.
kHalfWindowS = 1.0 / 60.0
# A mocap sample further than this from the wanted time is a dropout (TUM samples at 100 Hz).
kMaxGtGapS = 0.02
# Fewer frames than this, or a mocap rate below kMinRateRadS rms, cannot fix a slope.
kMinFrames = 10
kMinRateRadS = 0.05
kRateColumns = ("rolling_shutter_rate_x", "rolling_shutter_rate_y", "rolling_shutter_rate_z")


@dataclass(frozen=True)
class ReadoutEstimate:
    frames: int
    readout_s: float  # pooled over the three axes
    per_axis_s: tuple[float, float, float]
    correlation: tuple[float, float, float]
    mocap_rate_rms_rad_s: float


def read_rates(frames_csv: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Stamps and (N,3) rows' rates of the frames that have one."""
    stamps, rates = [], []
    with open(frames_csv, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        missing = [c for c in ("stamp_s", *kRateColumns) if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{frames_csv}: no column(s) {', '.join(missing)}")
        for row in reader:
            cells = [row[c] for c in kRateColumns]
            if any(c == "" for c in cells):
                continue
            stamps.append(float(row["stamp_s"]))
            rates.append([float(c) for c in cells])
    return np.asarray(stamps), np.asarray(rates).reshape(-1, 3)


def mocap_rates(gt: tum.Trajectory, stamps_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,3) camera-frame angular velocity of the ground truth at each stamp, and which stamps
    had ground truth on both sides within kMaxGtGapS."""
    lo_t, hi_t = stamps_s - kHalfWindowS, stamps_s + kHalfWindowS
    lo = np.abs(gt.stamps_s[None, :] - lo_t[:, None]).argmin(axis=1)
    hi = np.abs(gt.stamps_s[None, :] - hi_t[:, None]).argmin(axis=1)
    ok = (np.abs(gt.stamps_s[lo] - lo_t) <= kMaxGtGapS) & (
        np.abs(gt.stamps_s[hi] - hi_t) <= kMaxGtGapS
    )
    ok &= hi > lo
    dt = np.where(ok, gt.stamps_s[hi] - gt.stamps_s[lo], 1.0)
    rel = np.transpose(gt.poses[lo, :3, :3], (0, 2, 1)) @ gt.poses[hi, :3, :3]
    return se3.rotation_vector(rel) / dt[:, None], ok


def estimate_readout(
    rows_rate: np.ndarray, mocap_rate: np.ndarray, assumed_readout_s: float
) -> ReadoutEstimate:
    if len(rows_rate) < kMinFrames:
        raise ValueError(f"only {len(rows_rate)} frame(s) with a rate and ground truth")
    rms = float(np.sqrt(np.mean(np.sum(mocap_rate**2, axis=1))))
    if rms < kMinRateRadS:
        raise ValueError(f"the camera hardly turns ({rms:.3f} rad/s rms): no slope to measure")
    pooled = float(np.sum(rows_rate * mocap_rate) / np.sum(mocap_rate**2))
    per_axis = tuple(
        float(
            assumed_readout_s
            * np.sum(rows_rate[:, k] * mocap_rate[:, k])
            / np.sum(mocap_rate[:, k] ** 2)
        )
        for k in range(3)
    )
    corr = tuple(float(np.corrcoef(rows_rate[:, k], mocap_rate[:, k])[0, 1]) for k in range(3))
    return ReadoutEstimate(len(rows_rate), assumed_readout_s * pooled, per_axis, corr, rms)


def check(gt_path: str, frames_csv: str, assumed_readout_s: float) -> ReadoutEstimate:
    if not assumed_readout_s > 0:
        raise ValueError("the run must assume a readout > 0 (--readout-s or its metrics.json)")
    stamps, rows_rate = read_rates(frames_csv)
    mocap, ok = mocap_rates(tum.read_trajectory(gt_path), stamps)
    return estimate_readout(rows_rate[ok], mocap[ok], assumed_readout_s)


def format_estimate(e: ReadoutEstimate) -> str:
    axes = ", ".join(f"{v * 1000:.1f}" for v in e.per_axis_s)
    corr = ", ".join(f"{c:.2f}" for c in e.correlation)
    return (
        f"{e.frames} frames, mocap rate {e.mocap_rate_rms_rad_s:.2f} rad/s rms\n"
        f"readout {e.readout_s * 1000:.1f} ms (per axis x, y, z: {axes} ms; "
        f"correlation of the rows' rate with the mocap's: {corr})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--gt", required=True, help="ground truth, TUM format (motion capture)")
    parser.add_argument("--frames", required=True, help="frames.csv of a slam-eval run")
    parser.add_argument(
        "--readout-s",
        type=float,
        default=None,
        help="readout the run assumed (default: rolling_shutter_readout_s of the metrics.json "
        "beside frames.csv)",
    )
    args = parser.parse_args(argv)
    try:
        readout = args.readout_s
        if readout is None:
            metrics = Path(args.frames).with_name("metrics.json")
            readout = float(
                json.loads(metrics.read_text(encoding="utf-8"))["rolling_shutter_readout_s"]
            )
        estimate = check(args.gt, args.frames, readout)
    except (OSError, ValueError, KeyError, tum.TumFormatError) as e:
        print(f"rolling_shutter_check: {e}", file=sys.stderr)
        return 1
    print(format_estimate(estimate))
    return 0


if __name__ == "__main__":
    sys.exit(main())
