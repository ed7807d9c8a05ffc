#!/usr/bin/env python3
"""Stamp lag of an estimated trajectory against motion-capture ground truth, for orientation and
position separately.

    stamp_lag.py --gt groundtruth.txt --est trajectory.tum [--max-shift-ms 50] [--step-ms 5]

For each shift s the ground truth is read at (estimate stamp + s) - position interpolated
linearly, orientation interpolated between the two nearest motion-capture samples - and scored:

- position: RMSE after the rigid (Horn) alignment, exactly the benchmark's ATE at that shift;
- orientation: RMS angle of A R_est(t) B against R_gt(t + s), where the world-side rotation A
  and the camera-side rotation B (a hand-eye residual is not a timing error) are fitted to the
  orientations themselves, so that a position error cannot leak into the orientation figure
  through the position alignment.

The shift where each is smallest is where the ground truth agrees best with the estimate: a
negative shift means the estimate shows the camera as the ground truth had it |s| ms before the
estimate's stamp (the estimate lags its stamp). A stream whose stamps are taken after exposure (at
arrival, as the Kinect's colour stamps) makes every system's orientation lag; the benchmark's ATE
uses positions at the given stamps and cannot show it. docs/slam.md (Timestamps) has what it
prints for this project, RGBD-SLAM and ORB-SLAM2 on the shared excerpts.

Only estimate stamps whose shifted time falls inside the ground truth for every shift, between two
motion-capture samples at most `kMaxGtGapS` apart, are used, so all shifts score the same poses.
Exit status 1 with a message on unusable input.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

import numpy as np
from slam_study import se3, tum

# Interpolating across a motion-capture dropout would invent poses: the ground truth's samples
# around a shifted stamp may be at most this far apart (the TUM systems sample at 100 Hz; 50 ms
# allows a few missed samples, as the benchmark's 20 ms association window allows a missing one).
kMaxGtGapS = 0.05
# Three non-collinear positions fix a rigid alignment (the ATE's own minimum).
kMinPoses = 3
# Gauss-Newton steps of the world-side / camera-side rotation fit: it starts at the closed-form
# world-side mean, and for offsets of a few degrees converges to 1e-6 deg in 2-3 steps.
kOrientationAlignRounds = 5


@dataclass(frozen=True)
class ShiftScore:
    shift_s: float
    position_rmse_m: float
    orientation_rms_deg: float


@dataclass(frozen=True)
class LagReport:
    scores: list[ShiftScore]
    poses: int

    def best_position(self) -> ShiftScore:
        return min(self.scores, key=lambda s: s.position_rmse_m)

    def best_orientation(self) -> ShiftScore:
        return min(self.scores, key=lambda s: s.orientation_rms_deg)


def _interpolate(gt: tum.Trajectory, t: np.ndarray) -> np.ndarray:
    """(N,4,4) ground-truth poses at stamps t (all inside gt's span): linear position, normalised
    linear quaternion interpolation (exact to ~1e-6 rad for the 10 ms between mocap samples)."""
    hi = np.searchsorted(gt.stamps_s, t, side="right").clip(1, len(gt) - 1)
    lo = hi - 1
    w = ((t - gt.stamps_s[lo]) / (gt.stamps_s[hi] - gt.stamps_s[lo]))[:, None]
    pos = (1 - w) * gt.poses[lo, :3, 3] + w * gt.poses[hi, :3, 3]
    q_lo = np.array([se3.rot_to_quat_xyzw(r) for r in gt.poses[lo, :3, :3]])
    q_hi = np.array([se3.rot_to_quat_xyzw(r) for r in gt.poses[hi, :3, :3]])
    q_hi *= np.sign(np.sum(q_lo * q_hi, axis=1, keepdims=True) + 1e-300)
    poses = np.repeat(np.eye(4)[None], t.size, axis=0)
    poses[:, :3, :3] = se3.quat_xyzw_to_rot((1 - w) * q_lo + w * q_hi)
    poses[:, :3, 3] = pos
    return poses


def _usable(gt: tum.Trajectory, t: np.ndarray) -> np.ndarray:
    inside = (t >= gt.stamps_s[0]) & (t <= gt.stamps_s[-1])
    hi = np.searchsorted(gt.stamps_s, t, side="right").clip(1, len(gt) - 1)
    gap = gt.stamps_s[hi] - gt.stamps_s[hi - 1]
    return inside & (gap <= kMaxGtGapS)


def _mean_rotation(rot: np.ndarray) -> np.ndarray:
    """Chordal L2 mean of (N,3,3) rotations: the arithmetic mean projected onto SO(3)."""
    u, _, vt = np.linalg.svd(rot.mean(axis=0))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    return u @ d @ vt


def _exp(rotvec: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 0 else np.zeros(3)
    return se3.quat_xyzw_to_rot(np.append(axis * np.sin(angle / 2), np.cos(angle / 2)))


def _orientation_rms_deg(r_gt: np.ndarray, r_est: np.ndarray) -> float:
    """RMS angle between r_gt and A r_est B, with A (world side) and B (camera side) fitted by
    Gauss-Newton on the rotation-vector residuals log(r_gt^-1 A r_est B): to first order
    A <- exp(da) A, B <- B exp(db) changes residual i by M_i^T da + db, M_i = A r_est_i B. A small
    range of motion makes da and db nearly interchangeable; the least-squares step then takes the
    minimum-norm split, which leaves the residual - the figure reported - the same."""
    world = _mean_rotation(r_gt @ np.transpose(r_est, (0, 2, 1)))
    cam = np.eye(3)
    for _ in range(kOrientationAlignRounds):
        m = world @ r_est @ cam
        res = se3.rotation_vector(np.transpose(r_gt, (0, 2, 1)) @ m)
        jac = np.concatenate([np.transpose(m, (0, 2, 1)), np.repeat(np.eye(3)[None], len(m), 0)], 2)
        step = np.linalg.lstsq(jac.reshape(-1, 6), -res.reshape(-1), rcond=None)[0]
        world = _exp(step[:3]) @ world
        cam = cam @ _exp(step[3:])
    err = np.transpose(r_gt, (0, 2, 1)) @ (world @ r_est @ cam)
    return float(np.sqrt(np.mean(se3.rotation_angle_deg(err) ** 2)))


def score_shift(gt: tum.Trajectory, est: tum.Trajectory, shift_s: float) -> ShiftScore:
    gt_poses = _interpolate(gt, est.stamps_s + shift_s)
    rot, trans = se3.align_rigid(gt_poses[:, :3, 3], est.positions_m())
    aligned_pos = est.positions_m() @ rot.T + trans
    position_rmse = float(np.sqrt(np.mean(np.sum((aligned_pos - gt_poses[:, :3, 3]) ** 2, axis=1))))
    return ShiftScore(
        shift_s, position_rmse, _orientation_rms_deg(gt_poses[:, :3, :3], est.poses[:, :3, :3])
    )


def stamp_lag(
    gt: tum.Trajectory, est: tum.Trajectory, max_shift_s: float, step_s: float
) -> LagReport:
    """Scores est against gt at shifts -max_shift_s ... +max_shift_s (step_s apart)."""
    if not (max_shift_s >= 0 and step_s > 0 and np.isfinite(max_shift_s) and np.isfinite(step_s)):
        raise ValueError("the shift range must be >= 0 and the step > 0")
    steps = int(round(max_shift_s / step_s))
    shifts = np.arange(-steps, steps + 1) * step_s
    keep = np.ones(len(est), dtype=bool)
    for s in (shifts[0], shifts[-1], 0.0):
        keep &= _usable(gt, est.stamps_s + s)
    if keep.sum() < kMinPoses:
        raise ValueError(
            f"only {int(keep.sum())} estimated pose(s) lie inside the ground truth "
            f"for every shift of +-{max_shift_s * 1000:.0f} ms; need {kMinPoses}"
        )
    used = est.subset(np.where(keep)[0])
    return LagReport([score_shift(gt, used, float(s)) for s in shifts], len(used))


def format_report(report: LagReport, brief: bool = False) -> str:
    lines = (
        []
        if brief
        else [
            f"{report.poses} estimated poses, ground truth read at (stamp + shift)",
            "shift ms   position RMSE mm   orientation RMS deg",
        ]
    )
    for s in [] if brief else report.scores:
        lines.append(
            f"{s.shift_s * 1000:+8.1f}   {s.position_rmse_m * 1000:16.2f}   "
            f"{s.orientation_rms_deg:10.3f}"
        )
    bp, bo = report.best_position(), report.best_orientation()
    zero = min(report.scores, key=lambda s: abs(s.shift_s))
    lines.append(
        f"position best at {bp.shift_s * 1000:+.1f} ms ({bp.position_rmse_m * 1000:.2f} "
        f"mm; {zero.position_rmse_m * 1000:.2f} mm at 0)"
    )
    lines.append(
        f"orientation best at {bo.shift_s * 1000:+.1f} ms ({bo.orientation_rms_deg:.3f} "
        f"deg; {zero.orientation_rms_deg:.3f} deg at 0)"
    )
    edge = max(abs(report.scores[0].shift_s), abs(report.scores[-1].shift_s))
    if abs(bp.shift_s) >= edge or abs(bo.shift_s) >= edge:
        lines.append("a best shift is at the edge of the range: widen --max-shift-ms")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--gt", required=True, help="ground truth, TUM format (motion capture)")
    parser.add_argument("--est", required=True, help="estimate, TUM format")
    parser.add_argument(
        "--max-shift-ms",
        type=float,
        default=50.0,
        help="largest shift tried either way (default 50 ms: 1.5 frames at 30 fps)",
    )
    parser.add_argument("--step-ms", type=float, default=5.0, help="shift step (default 5 ms)")
    parser.add_argument("--brief", action="store_true", help="only the two best shifts, no table")
    args = parser.parse_args(argv)
    try:
        report = stamp_lag(
            tum.read_trajectory(args.gt),
            tum.read_trajectory(args.est),
            args.max_shift_ms / 1000.0,
            args.step_ms / 1000.0,
        )
    except (tum.TumFormatError, ValueError) as err:
        print(f"stamp_lag: {err}", file=sys.stderr)
        return 1
    print(format_report(report, brief=args.brief))
    return 0


if __name__ == "__main__":
    sys.exit(main())
