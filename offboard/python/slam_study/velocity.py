"""Frame-rate reduction statistics (thesis Table 3.4 style): keeping every k-th frame of a ~30 fps
recording turns one dataset into several with more motion per frame.

Velocities come from ground truth at the kept frames' stamps (nearest within 20 ms): translational
m/s = mean of |delta t| / delta time over consecutive kept frames, rotational deg/s likewise with
the rotation angle; per-frame motion is the mean of |delta t| (mm) and angle (deg) per kept pair.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slam_study import se3
from slam_study.tables import Table
from slam_study.tum import Dataset

# The Kinect v1 records at ~30 Hz; 30/k is the nominal reduced rate printed beside the measured one.
kNominalFps = 30.0


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


def rate_stats(dataset: Dataset, k: int) -> RateStats | None:
    """Statistics of `dataset` reduced to every k-th frame; None when fewer than 2 frames remain."""
    if k < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    gt = dataset.groundtruth_at_frames(k)
    if len(gt) < 2:
        return None
    rel = se3.relative(gt.poses[:-1], gt.poses[1:])
    dt = np.diff(gt.stamps_s)
    trans_m = np.linalg.norm(rel[:, :3, 3], axis=1)
    rot_deg = se3.rotation_angle_deg(rel[:, :3, :3])
    duration = float(gt.stamps_s[-1] - gt.stamps_s[0])
    frames = int(dataset.rgb_stamps_s[::k].size)
    return RateStats(k, kNominalFps / k, (len(gt) - 1) / duration if duration > 0 else float("nan"),
                     duration, frames, float(np.mean(trans_m / dt)), float(np.mean(rot_deg / dt)),
                     float(1000 * trans_m.mean()), float(rot_deg.mean()))


def rate_table(dataset: Dataset, ks: list[int]) -> Table:
    table = Table(f"table_3_4_{dataset.name}",
                  f"Table 3.4 - {dataset.name} at reduced frame rates (every k-th frame)",
                  ["k", "fps (nominal)", "fps (measured)", "duration s", "frames",
                   "trans m/s", "rot deg/s", "mm/frame", "deg/frame"])
    for k in ks:
        s = rate_stats(dataset, k)
        if s is None:
            table.rows.append([str(k), f"{kNominalFps / k:.2f}", "-", "-",
                               str(dataset.rgb_stamps_s[::k].size), "-", "-", "-", "-"])
            continue
        table.rows.append([str(k), f"{s.nominal_fps:.2f}", f"{s.fps:.2f}", f"{s.duration_s:.2f}",
                           str(s.frames), f"{s.trans_m_per_s:.3f}", f"{s.rot_deg_per_s:.2f}",
                           f"{s.trans_mm_per_frame:.2f}", f"{s.rot_deg_per_frame:.3f}"])
    return table
