"""Frame-rate reduction statistics (thesis Table 3.4 style): keeping every k-th frame of a ~30 fps
recording turns one dataset into several with more motion per frame.

Velocities follow the benchmark's (and thesis Table 3.3's) definition: the mean over ground-truth
samples of the motion over the following 1 s, divided by that second (translation m/s, rotation
angle deg/s). Over a whole ground-truth file this reproduces Table 3.3 to its printed digits
(fr1/desk 0.413 m/s, 23.3 deg/s; fr1/xyz 0.244 m/s, 8.91 deg/s; test_tables.py); Table 3.4 takes
it within the span of the kept frames, so excerpts get their own velocity. It does not
depend on k; what k changes is the motion per frame: the mean |delta t| (mm) and angle (deg)
between consecutive kept frames (ground truth nearest within 20 ms).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slam_study import se3
from slam_study.tables import Table
from slam_study.tum import Dataset, Trajectory

# The Kinect v1 records at ~30 Hz; 30/k is the nominal reduced rate printed beside the measured one.
kNominalFps = 30.0
# Window of the velocity definition (TUM benchmark statistics / thesis Table 3.3). Excerpts
# shorter than this use their whole span (the table prints the window used).
kVelocityWindowS = 1.0


@dataclass(frozen=True)
class RateStats:
    k: int
    nominal_fps: float
    fps: float
    duration_s: float
    frames: int
    trans_m_per_s: float
    rot_deg_per_s: float
    trans_mm_per_frame: float
    rot_deg_per_frame: float
    window_s: float


def window_velocities(
    gt: Trajectory, start_s: float, end_s: float, window_s: float = kVelocityWindowS
) -> tuple[np.ndarray, np.ndarray, float]:
    """(m/s per window, deg/s per window, window used): the motion over the `window` seconds that
    follow each ground-truth sample inside [start_s, end_s], per second. The window shrinks to the
    span when the span is shorter; empty arrays with fewer than 2 samples."""
    inside = np.where((gt.stamps_s >= start_s) & (gt.stamps_s <= end_s))[0]
    if inside.size < 2:
        return np.zeros(0), np.zeros(0), 0.0
    stamps = gt.stamps_s[inside]
    window = min(window_s, float(stamps[-1] - stamps[0]))
    j = np.searchsorted(stamps, stamps + window - 1e-9)
    valid = j < stamps.size
    i, j = np.where(valid)[0], j[valid]
    rel = se3.relative(gt.poses[inside[i]], gt.poses[inside[j]])
    dt = stamps[j] - stamps[i]
    return (
        np.linalg.norm(rel[:, :3, 3], axis=1) / dt,
        se3.rotation_angle_deg(rel[:, :3, :3]) / dt,
        window,
    )


def windowed_velocity(
    gt: Trajectory, start_s: float, end_s: float, window_s: float = kVelocityWindowS
) -> tuple[float, float, float]:
    """(m/s, deg/s, window used): mean motion over `window` seconds of the ground truth inside
    [start_s, end_s], per second. The window shrinks to the span when the span is shorter."""
    v, w, window = window_velocities(gt, start_s, end_s, window_s)
    if v.size == 0:
        return float("nan"), float("nan"), window
    return float(np.mean(v)), float(np.mean(w)), window


def rate_stats(dataset: Dataset, k: int) -> RateStats | None:
    """Statistics of `dataset` reduced to every k-th frame; None when fewer than 2 frames remain."""
    if k < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    gt = dataset.groundtruth_at_frames(k)
    if len(gt) < 2:
        return None
    rel = se3.relative(gt.poses[:-1], gt.poses[1:])
    trans_m = np.linalg.norm(rel[:, :3, 3], axis=1)
    rot_deg = se3.rotation_angle_deg(rel[:, :3, :3])
    duration = float(gt.stamps_s[-1] - gt.stamps_s[0])
    frames = int(dataset.rgb_stamps_s[::k].size)
    v_m_s, w_deg_s, window = windowed_velocity(dataset.groundtruth, gt.stamps_s[0], gt.stamps_s[-1])
    return RateStats(
        k,
        kNominalFps / k,
        (len(gt) - 1) / duration if duration > 0 else float("nan"),
        duration,
        frames,
        v_m_s,
        w_deg_s,
        float(1000 * trans_m.mean()),
        float(rot_deg.mean()),
        window,
    )


def rate_table(dataset: Dataset, ks: list[int]) -> Table:
    table = Table(
        f"table_3_4_{dataset.name}",
        f"Table 3.4 - {dataset.name} at reduced frame rates (every k-th frame)",
        [
            "k",
            "fps (nominal)",
            "fps (measured)",
            "duration s",
            "frames",
            "trans m/s",
            "rot deg/s",
            "velocity window s",
            "mm/frame",
            "deg/frame",
        ],
    )
    for k in ks:
        s = rate_stats(dataset, k)
        if s is None:
            table.rows.append(
                [
                    str(k),
                    f"{kNominalFps / k:.2f}",
                    "-",
                    "-",
                    str(dataset.rgb_stamps_s[::k].size),
                    "-",
                    "-",
                    "-",
                    "-",
                    "-",
                ]
            )
            continue
        table.rows.append(
            [
                str(k),
                f"{s.nominal_fps:.2f}",
                f"{s.fps:.2f}",
                f"{s.duration_s:.2f}",
                str(s.frames),
                f"{s.trans_m_per_s:.3f}",
                f"{s.rot_deg_per_s:.2f}",
                f"{s.window_s:.2f}",
                f"{s.trans_mm_per_frame:.2f}",
                f"{s.rot_deg_per_frame:.3f}",
            ]
        )
    return table
