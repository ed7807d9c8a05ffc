"""PNG figures of the report (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import itertools

import matplotlib.pyplot as plt
import numpy as np

from slam_study import tables
from slam_study.pairs import PairTable, kRotAxes, kTransAxes
from slam_study.tum import Trajectory

kAxisColours = ("tab:red", "tab:green", "tab:blue")


def _bin_means(x: np.ndarray, y: np.ndarray, edges) -> tuple[np.ndarray, np.ndarray]:
    centres, means = [], []
    for lo, hi in itertools.pairwise(edges):
        sel = tables.in_bin(x, lo, hi)
        if sel.sum() >= tables.kMinSamplesPerCell:
            centres.append(0.5 * (lo + hi))
            means.append(y[sel].mean())
    return np.array(centres), np.array(means)


def error_vs_motion(pairs: PairTable, path: Path, title: str, rotation: bool) -> None:
    """Scatter of translational and rotational RPE against the per-frame motion of the pure-
    translation (rotation=False) or pure-rotation pairs, single-axis pairs coloured by axis, with
    bin means (bins with >= kMinSamplesPerCell pairs)."""
    if rotation:
        pure = pairs.select(pairs.gt_trans_mm < tables.kRotStudyMaxTransMm)
        x, shares, names = pure.gt_rot_deg, pure.rot_share, kRotAxes
        threshold, edges, xlabel = (
            tables.kRotSingleAxisShare,
            tables.kRotStudyEdgesDeg,
            "ground-truth rotation per frame (deg), translation < 3 mm",
        )
    else:
        pure = pairs.select(pairs.gt_rot_deg < tables.kTransStudyMaxRotDeg)
        x, shares, names = pure.gt_trans_mm, pure.trans_share, kTransAxes
        threshold, edges, xlabel = (
            tables.kTransSingleAxisShare,
            tables.kTransStudyEdgesMm,
            "ground-truth translation per frame (mm), rotation < 0.3 deg",
        )
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, y, ylabel in (
        (axes[0], pure.rpe_trans_mm, "translational RPE (mm)"),
        (axes[1], pure.rpe_rot_deg, "rotational RPE (deg)"),
    ):
        single_any = np.zeros(len(pure), dtype=bool)
        for i, name in enumerate(names):
            sel = shares[:, i] > threshold
            single_any |= sel
            ax.scatter(
                x[sel],
                y[sel],
                s=8,
                color=kAxisColours[i],
                alpha=0.6,
                label=f"{name} single-axis (n={int(sel.sum())})",
            )
            cx, cy = _bin_means(x[sel], y[sel], edges)
            if cx.size:
                ax.plot(cx, cy, "-o", color=kAxisColours[i], lw=1.5, ms=4)
        ax.scatter(
            x[~single_any],
            y[~single_any],
            s=6,
            color="0.6",
            alpha=0.4,
            label=f"mixed axes (n={int((~single_any).sum())})",
        )
        cx, cy = _bin_means(x, y, edges)
        if cx.size:
            ax.plot(cx, cy, "--", color="k", lw=1.5, label="bin mean, all")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{title} (n={len(pure)} pairs)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def grid_heatmap(cells, path: Path, title: str) -> None:
    """Heat maps of the 9x9 grid's mean translational and rotational RPE, n written in each cell."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    t_lab = [
        tables.bin_label(a, b)
        for a, b in zip(tables.kGridTransEdgesMm[:-1], tables.kGridTransEdgesMm[1:], strict=False)
    ]
    r_lab = [
        tables.bin_label(a, b)
        for a, b in zip(tables.kGridRotEdgesDeg[:-1], tables.kGridRotEdgesDeg[1:], strict=False)
    ]
    for ax, attr, label in (
        (axes[0], "trans_mean_mm", "translational RPE mean (mm)"),
        (axes[1], "rot_mean_deg", "rotational RPE mean (deg)"),
    ):
        values = np.array([[getattr(c, attr) if c.n > 0 else np.nan for c in row] for row in cells])
        image = ax.imshow(
            np.ma.masked_invalid(values), origin="lower", cmap="viridis", aspect="auto"
        )
        for i, row in enumerate(cells):
            for j, c in enumerate(row):
                if c.n > 0:
                    colour = "w" if c.n >= tables.kMinSamplesPerCell else "r"
                    ax.text(
                        j,
                        i,
                        f"{getattr(c, attr):.2g}\nn={c.n}",
                        ha="center",
                        va="center",
                        fontsize=6,
                        color=colour,
                    )
        ax.set_xticks(range(len(r_lab)), r_lab, rotation=45, fontsize=7)
        ax.set_yticks(range(len(t_lab)), t_lab, fontsize=7)
        ax.set_xlabel("rotation per frame (deg)")
        ax.set_ylabel("translation per frame (mm)")
        ax.set_title(label, fontsize=9)
        fig.colorbar(image, ax=ax)
    fig.suptitle(f"{title} - red n: fewer than {tables.kMinSamplesPerCell} pairs")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def trajectories_top_down(
    groundtruth: Trajectory, estimates: dict[str, Trajectory], path: Path, title: str
) -> None:
    """x-y (top-down; the mocap world's z is up) ground truth against ATE-aligned estimates."""
    fig, ax = plt.subplots(figsize=(6.5, 6))
    gt = groundtruth.positions_m()
    ax.plot(gt[:, 0], gt[:, 1], "k-", lw=2.5, label="ground truth")
    for name, traj in estimates.items():
        p = traj.positions_m()
        ax.plot(p[:, 0], p[:, 1], "-", lw=1, label=name)
    ax.set_xlabel("x (m, world)")
    ax.set_ylabel("y (m, world)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
