"""Binning of per-pair records into the thesis's tables, and Markdown/CSV rendering.

Bin edges (per-frame ground-truth motion) and selection thresholds come from the thesis, as quoted
in the study issue:
  Tables 4.14/4.15 translation study: pairs with rotation < 0.3 deg, 1-2, 2-4, 4-6, 6-8, 8-10,
    10-15, 15-19 mm; single-axis when one of x/y/z holds > 80 % of the translation.
  Tables 4.17/4.18 rotation study: pairs with translation < 3 mm, 0.1-0.2 ... 1.5-1.9 deg; the
    issue elides the middle edges, we mirror the translation bins at 1/10 scale (0.1-0.2, 0.2-0.4,
    0.4-0.6, 0.6-0.8, 0.8-1.0, 1.0-1.5, 1.5-1.9); single-axis when roll/pitch/yaw holds > 85 %.
  Table 4.20 joint grid: translation 1-2, 2-4, ..., 16-18 mm x rotation 0.1-0.2, 0.2-0.4, ...,
    1.6-1.8.
Bins are half-open [lo, hi).
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from slam_study.pairs import PairTable, kRotAxes, kTransAxes

kTransStudyMaxRotDeg = 0.3  # Table 4.14: "pure" translation pairs rotate less than this
kRotStudyMaxTransMm = 3.0  # Table 4.17: "pure" rotation pairs translate less than this
kTransSingleAxisShare = 0.80  # Table 4.15: single-axis translation threshold
kRotSingleAxisShare = 0.85  # Table 4.18: single-axis rotation threshold
kTransStudyEdgesMm = (1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 15.0, 19.0)
kRotStudyEdgesDeg = (0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.5, 1.9)
kGridTransEdgesMm = (1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0)
kGridRotEdgesDeg = (0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8)
# Velocity-only tables (4.16, 4.19) restate the per-frame bins as velocities at these rates.
kVelocityTableFps = (30.0, 20.0, 10.0)
# A cell with fewer pairs than this is shown but flagged "thin": its mean is not trustworthy.
kMinSamplesPerCell = 5


@dataclass
class CellStats:
    n: int
    trans_mean_mm: float
    trans_std_mm: float
    rot_mean_deg: float
    rot_std_deg: float
    motion_trans_mean_mm: float
    motion_rot_mean_deg: float

    @staticmethod
    def of(pairs: PairTable) -> CellStats:
        n = len(pairs)
        if n == 0:
            nan = float("nan")
            return CellStats(0, nan, nan, nan, nan, nan, nan)
        return CellStats(
            n,
            float(pairs.rpe_trans_mm.mean()),
            float(pairs.rpe_trans_mm.std()),
            float(pairs.rpe_rot_deg.mean()),
            float(pairs.rpe_rot_deg.std()),
            float(pairs.gt_trans_mm.mean()),
            float(pairs.gt_rot_deg.mean()),
        )

    def trans_text(self) -> str:
        return "-" if self.n == 0 else f"{self.trans_mean_mm:.2f} ± {self.trans_std_mm:.2f}"

    def rot_text(self) -> str:
        return "-" if self.n == 0 else f"{self.rot_mean_deg:.3f} ± {self.rot_std_deg:.3f}"

    def n_text(self) -> str:
        return f"{self.n}" + (" (thin)" if 0 < self.n < kMinSamplesPerCell else "")


@dataclass
class Table:
    """A titled table: header + rows of strings, rendered to Markdown or CSV."""

    key: str  # file stem, e.g. "table_4_14_translation"
    title: str
    header: list[str]
    rows: list[list[str]] = field(default_factory=list)
    note: str = ""

    def markdown(self) -> str:
        out = [f"### {self.title}", ""]
        if self.note:
            out += [self.note, ""]
        out.append("| " + " | ".join(self.header) + " |")
        out.append("|" + "---|" * len(self.header))
        for row in self.rows:
            out.append("| " + " | ".join(row) + " |")
        if not self.rows:
            out.append("| " + " | ".join(["(no data)"] + [""] * (len(self.header) - 1)) + " |")
        return "\n".join(out) + "\n"

    def csv(self) -> str:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(self.header)
        writer.writerows(self.rows)
        return buf.getvalue()


def bin_label(lo: float, hi: float) -> str:
    return f"{lo:g}-{hi:g}"


def in_bin(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return (values >= lo) & (values < hi)


def _fmt(x: float, digits: int = 2) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def _pct(err: float, motion: float) -> str:
    if math.isnan(err) or math.isnan(motion) or motion <= 0:
        return "-"
    return f"{100.0 * err / motion:.0f} %"


def translation_study(pairs: PairTable) -> tuple[Table, Table]:
    """Tables 4.14 (all axes) and 4.15 (single-axis x/y/z) for rotation < 0.3 deg."""
    pure = pairs.select(pairs.gt_rot_deg < kTransStudyMaxRotDeg)
    edges = kTransStudyEdgesMm
    t414 = Table(
        "table_4_14_translation",
        "Table 4.14 - translation study: pairs rotating < 0.3 deg, by translation per frame",
        [
            "translation mm/frame",
            "n",
            "RPE trans mm (mean ± std)",
            "trans err %",
            "RPE rot deg (mean ± std)",
        ],
    )
    for lo, hi in itertools.pairwise(edges):
        c = CellStats.of(pure.select(in_bin(pure.gt_trans_mm, lo, hi)))
        t414.rows.append(
            [
                bin_label(lo, hi),
                c.n_text(),
                c.trans_text(),
                _pct(c.trans_mean_mm, c.motion_trans_mean_mm),
                c.rot_text(),
            ]
        )
    t415 = Table(
        "table_4_15_translation_axes",
        "Table 4.15 - single-axis translation (> 80 % of |t| on one camera axis), "
        "RPE trans mm mean ± std [n]",
        ["translation mm/frame"] + [f"{a} (camera)" for a in kTransAxes],
    )
    for lo, hi in itertools.pairwise(edges):
        row = [bin_label(lo, hi)]
        for ax in range(3):
            sel = in_bin(pure.gt_trans_mm, lo, hi) & (
                pure.trans_share[:, ax] > kTransSingleAxisShare
            )
            c = CellStats.of(pure.select(sel))
            row.append(f"{c.trans_text()} [{c.n_text()}]")
        t415.rows.append(row)
    return t414, t415


def rotation_study(pairs: PairTable) -> tuple[Table, Table]:
    """Tables 4.17 (all axes) and 4.18 (single-axis roll/pitch/yaw) for translation < 3 mm."""
    pure = pairs.select(pairs.gt_trans_mm < kRotStudyMaxTransMm)
    edges = kRotStudyEdgesDeg
    t417 = Table(
        "table_4_17_rotation",
        "Table 4.17 - rotation study: pairs translating < 3 mm, by rotation per frame",
        [
            "rotation deg/frame",
            "n",
            "RPE trans mm (mean ± std)",
            "RPE rot deg (mean ± std)",
            "rot err %",
        ],
    )
    for lo, hi in itertools.pairwise(edges):
        c = CellStats.of(pure.select(in_bin(pure.gt_rot_deg, lo, hi)))
        t417.rows.append(
            [
                bin_label(lo, hi),
                c.n_text(),
                c.trans_text(),
                c.rot_text(),
                _pct(c.rot_mean_deg, c.motion_rot_mean_deg),
            ]
        )
    t418 = Table(
        "table_4_18_rotation_axes",
        "Table 4.18 - single-axis rotation (> 85 % of the rotation vector on one axis), "
        "RPE rot deg mean ± std [n]",
        ["rotation deg/frame"] + [f"{a}" for a in kRotAxes],
    )
    for lo, hi in itertools.pairwise(edges):
        row = [bin_label(lo, hi)]
        for ax in range(3):
            sel = in_bin(pure.gt_rot_deg, lo, hi) & (pure.rot_share[:, ax] > kRotSingleAxisShare)
            c = CellStats.of(pure.select(sel))
            row.append(f"{c.rot_text()} [{c.n_text()}]")
        t418.rows.append(row)
    return t417, t418


def grid_cells(
    pairs: PairTable, trans_edges=kGridTransEdgesMm, rot_edges=kGridRotEdgesDeg
) -> list[list[CellStats]]:
    """cells[i][j]: translation bin i x rotation bin j."""
    cells = []
    for tlo, thi in itertools.pairwise(trans_edges):
        row = []
        in_t = in_bin(pairs.gt_trans_mm, tlo, thi)
        for rlo, rhi in itertools.pairwise(rot_edges):
            row.append(CellStats.of(pairs.select(in_t & in_bin(pairs.gt_rot_deg, rlo, rhi))))
        cells.append(row)
    return cells


def joint_grid(pairs: PairTable) -> tuple[Table, Table, list[list[CellStats]]]:
    """Table 4.20: 9x9 grid; one table of translational, one of rotational RPE (each with n)."""
    cells = grid_cells(pairs)
    rot_labels = [bin_label(a, b) for a, b in itertools.pairwise(kGridRotEdgesDeg)]
    t_tab = Table(
        "table_4_20_grid_trans",
        "Table 4.20a - joint grid, translational RPE mm mean ± std [n]; rows translation "
        "mm/frame, columns rotation deg/frame",
        ["mm \\ deg"] + rot_labels,
    )
    r_tab = Table(
        "table_4_20_grid_rot",
        "Table 4.20b - joint grid, rotational RPE deg mean ± std [n]",
        ["mm \\ deg"] + rot_labels,
    )
    for (tlo, thi), row in zip(itertools.pairwise(kGridTransEdgesMm), cells, strict=False):
        t_tab.rows.append([bin_label(tlo, thi)] + [f"{c.trans_text()} [{c.n}]" for c in row])
        r_tab.rows.append([bin_label(tlo, thi)] + [f"{c.rot_text()} [{c.n}]" for c in row])
    return t_tab, r_tab, cells


def velocity_tables(pairs: PairTable) -> tuple[Table, Table]:
    """Tables 4.16 / 4.19: the pure-translation and pure-rotation bins restated as velocities
    (per-frame motion x frame rate) at 30, 20 and 10 fps, with the error measured in that bin."""
    pure_t = pairs.select(pairs.gt_rot_deg < kTransStudyMaxRotDeg)
    t416 = Table(
        "table_4_16_trans_velocity",
        "Table 4.16 - translation bins as velocity (m/s) at 30 / 20 / 10 fps",
        ["mm/frame"]
        + [f"m/s @ {f:g} fps" for f in kVelocityTableFps]
        + ["n", "RPE trans mm", "RPE trans mm/s @ 30 fps"],
    )
    e = kTransStudyEdgesMm
    for lo, hi in itertools.pairwise(e):
        c = CellStats.of(pure_t.select(in_bin(pure_t.gt_trans_mm, lo, hi)))
        t416.rows.append(
            [bin_label(lo, hi)]
            + [f"{lo * f / 1000:.3f}-{hi * f / 1000:.3f}" for f in kVelocityTableFps]
            + [c.n_text(), c.trans_text(), _fmt(c.trans_mean_mm * 30.0, 1)]
        )
    pure_r = pairs.select(pairs.gt_trans_mm < kRotStudyMaxTransMm)
    t419 = Table(
        "table_4_19_rot_velocity",
        "Table 4.19 - rotation bins as angular velocity (deg/s) at 30 / 20 / 10 fps",
        ["deg/frame"]
        + [f"deg/s @ {f:g} fps" for f in kVelocityTableFps]
        + ["n", "RPE rot deg", "RPE trans mm"],
    )
    e = kRotStudyEdgesDeg
    for lo, hi in itertools.pairwise(e):
        c = CellStats.of(pure_r.select(in_bin(pure_r.gt_rot_deg, lo, hi)))
        t419.rows.append(
            [bin_label(lo, hi)]
            + [f"{lo * f:.1f}-{hi * f:.1f}" for f in kVelocityTableFps]
            + [c.n_text(), c.rot_text(), c.trans_text()]
        )
    return t416, t419
