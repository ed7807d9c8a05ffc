#!/usr/bin/env python3
"""Top-down plot (x-y of the TUM world frame) of an estimated trajectory against ground truth.

The estimate is first mapped into the ground-truth frame with the rigid alignment that
`slam-eval score` reports (T_gt_est_xyz_m, T_gt_est_qxyzw), i.e. the one the ATE uses.
Also prints where the trajectory went (start, end, path length).

usage: plot_trajectory.py GT.txt EST.tum SCORE.json OUT.png
"""

import json
import sys

import numpy as np


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            rows.append([float(x) for x in line.replace(",", " ").split()[:8]])
    return np.array(rows)


def quat_to_rot(qx, qy, qz, qw):
    n = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    qx, qy, qz, qw = qx / n, qy / n, qz / n, qw / n
    return np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )


def main(argv):
    if len(argv) != 5:
        print(__doc__, file=sys.stderr)
        return 2
    gt, est = read_tum(argv[1]), read_tum(argv[2])
    score = json.load(open(argv[3]))
    if len(est) == 0 or len(gt) == 0:
        print("plot_trajectory: empty trajectory", file=sys.stderr)
        return 1
    R = quat_to_rot(*score["T_gt_est_qxyzw"])
    t = np.array(score["T_gt_est_xyz_m"])
    est_xyz = est[:, 1:4] @ R.T + t
    # Ground truth over the estimate's time span only (+-0.1 s).
    span = (gt[:, 0] >= est[0, 0] - 0.1) & (gt[:, 0] <= est[-1, 0] + 0.1)
    gt_xyz = gt[span, 1:4]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 6), dpi=100)
    ax.plot(gt_xyz[:, 0], gt_xyz[:, 1], "k-", lw=2, label="ground truth (motion capture)")
    ax.plot(est_xyz[:, 0], est_xyz[:, 1], "r.-", ms=3, lw=1, label="SLAM estimate (aligned)")
    ax.plot(est_xyz[0, 0], est_xyz[0, 1], "go", label="start")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"top-down view, ATE RMSE {score['ate_rmse_m'] * 1000:.1f} mm")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(argv[4])
    path_len = float(np.sum(np.linalg.norm(np.diff(est_xyz, axis=0), axis=1)))
    print(
        f"trajectory: {len(est)} poses over {est[-1, 0] - est[0, 0]:.2f} s, "
        f"path length {path_len:.3f} m, "
        f"start ({est_xyz[0, 0]:.3f}, {est_xyz[0, 1]:.3f}, {est_xyz[0, 2]:.3f}) m, "
        f"end ({est_xyz[-1, 0]:.3f}, {est_xyz[-1, 1]:.3f}, {est_xyz[-1, 2]:.3f}) m "
        "(ground-truth frame)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
