"""Frame-rate guidance from the measured grid: `slam-study guide` and Table 4.21.

Given a platform's translational (m/s) and rotational (deg/s) velocity, the per-frame motion at a
frame rate f is v/f and w/f; the prediction is the measured RPE of the grid cell holding that
motion. The guide's grid is Table 4.20's plus a first row/column for motion below 1 mm / 0.1 deg
(slow platforms) and coarser cells beyond 18 mm / 1.8 deg (slow frame rates). A cell with fewer than kMinSamplesPerCell pairs, or motion
beyond the last edge, is answered "not enough data", never extrapolated.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from slam_study import tables
from slam_study.pairs import PairTable
from slam_study.tables import CellStats, Table

# Beyond the thesis's 18 mm / 1.8 deg the guide keeps going with coarser cells: reduced-rate runs
# (k up to 8) reach ~90 mm and ~4 deg per frame on fr1/xyz (Table 3.4), and a slow frame rate is
# exactly what the guide is asked about.
kGuideTransEdgesMm = (0.0,) + tables.kGridTransEdgesMm + (25.0, 35.0, 50.0, 70.0, 100.0)
kGuideRotEdgesDeg = (0.0,) + tables.kGridRotEdgesDeg + (2.5, 3.5, 5.0)
# Candidate rates: what keeping every k-th frame of the Kinect's 30 fps gives, k = 1..8.
kCandidateFps = tuple(30.0 / k for k in range(1, 9))
# Table 4.21's rates: the thesis's platform estimate spans 6-30 fps.
kPlatformFps = (30.0, 20.0, 15.0, 10.0, 7.5, 6.0)


@dataclass(frozen=True)
class Prediction:
    fps: float
    trans_mm_per_frame: float
    rot_deg_per_frame: float
    cell: CellStats | None      # None: motion beyond the measured range
    trans_bin: str
    rot_bin: str

    @property
    def enough(self) -> bool:
        return self.cell is not None and self.cell.n >= tables.kMinSamplesPerCell


def _locate(value: float, edges) -> int | None:
    for i, (lo, hi) in enumerate(itertools.pairwise(edges)):
        if lo <= value < hi:
            return i
    return None


def predict(pairs: PairTable, trans_m_per_s: float, rot_deg_per_s: float,
            fps_list=kCandidateFps) -> list[Prediction]:
    if not (np.isfinite(trans_m_per_s) and np.isfinite(rot_deg_per_s)):
        raise ValueError("velocities must be finite")
    if trans_m_per_s < 0 or rot_deg_per_s < 0:
        raise ValueError("velocities must be >= 0 (they are magnitudes)")
    out = []
    for fps in fps_list:
        t_mm = 1000.0 * trans_m_per_s / fps
        r_deg = rot_deg_per_s / fps
        ti = _locate(t_mm, kGuideTransEdgesMm)
        ri = _locate(r_deg, kGuideRotEdgesDeg)
        if ti is None or ri is None:
            out.append(Prediction(fps, t_mm, r_deg, None, "beyond grid", "beyond grid"))
            continue
        tlo, thi = kGuideTransEdgesMm[ti], kGuideTransEdgesMm[ti + 1]
        rlo, rhi = kGuideRotEdgesDeg[ri], kGuideRotEdgesDeg[ri + 1]
        sel = tables.in_bin(pairs.gt_trans_mm, tlo, thi) & tables.in_bin(pairs.gt_rot_deg, rlo, rhi)
        out.append(Prediction(fps, t_mm, r_deg, CellStats.of(pairs.select(sel)),
                              tables.bin_label(tlo, thi), tables.bin_label(rlo, rhi)))
    return out


def lowest_fps_meeting(preds: list[Prediction], target_rpe_mm: float) -> Prediction | None:
    """Going down from the highest candidate rate, the last rate whose cell has enough data and a
    mean translational RPE at or below the target, stopping at the first rate that misses it (a
    noisy dip below a failing rate is not trusted: error grows with motion per frame). Rates
    without enough data are passed over."""
    best = None
    for p in sorted(preds, key=lambda p: -p.fps):
        if not p.enough:
            continue
        if p.cell.trans_mean_mm > target_rpe_mm:
            break
        best = p
    return best


def guide_text(preds: list[Prediction], trans_m_per_s: float, rot_deg_per_s: float,
               target_rpe_mm: float | None, source: str) -> str:
    lines = [f"Frame-to-frame error predicted for {trans_m_per_s:g} m/s and {rot_deg_per_s:g} deg/s",
             f"(grid measured on: {source}; a cell needs >= {tables.kMinSamplesPerCell} pairs)", "",
             (f"{'fps':>6} {'mm/frame':>9} {'deg/frame':>9}  {'cell mm x deg':>16}  {'n':>5}  "
             f"{'RPE trans mm':>16}  {'RPE rot deg':>16}")]
    for p in preds:
        cell = f"{p.trans_bin} x {p.rot_bin}" if p.cell is not None else "beyond grid"
        if p.cell is None:
            verdict = "not enough data (motion beyond the measured range)"
            lines.append(f"{p.fps:6.2f} {p.trans_mm_per_frame:9.2f} {p.rot_deg_per_frame:9.3f}  "
                         f"{cell:>16}  {'-':>5}  {verdict}")
        elif not p.enough:
            lines.append(f"{p.fps:6.2f} {p.trans_mm_per_frame:9.2f} {p.rot_deg_per_frame:9.3f}  "
                         f"{cell:>16}  {p.cell.n:5d}  not enough data")
        else:
            lines.append(f"{p.fps:6.2f} {p.trans_mm_per_frame:9.2f} {p.rot_deg_per_frame:9.3f}  "
                         f"{cell:>16}  {p.cell.n:5d}  {p.cell.trans_text():>16}  "
                         f"{p.cell.rot_text():>16}")
    if target_rpe_mm is not None:
        best = lowest_fps_meeting(preds, target_rpe_mm)
        lines.append("")
        if best is None:
            lines.append(f"No candidate rate is known to meet {target_rpe_mm:g} mm per frame "
                         "(either the error is higher or the grid has not enough data there).")
        else:
            lines.append(f"Lowest frame rate meeting {target_rpe_mm:g} mm per frame: "
                         f"{best.fps:.2f} fps (predicted {best.cell.trans_text()} mm, "
                         f"n={best.cell.n}).")
            thin_below = [p for p in preds if p.fps < best.fps and not p.enough]
            if thin_below:
                lines.append("Lower rates have not enough data to say: "
                             + ", ".join(f"{p.fps:.2f}" for p in thin_below) + " fps.")
    return "\n".join(lines) + "\n"


def platform_table(pairs: PairTable) -> Table:
    """Table 4.21: at each rate, the fastest platform motion the measured data covers (upper edge
    of the largest pure-motion bin with enough pairs, times the rate) and the error measured there."""
    table = Table("table_4_21_platform",
                  "Table 4.21 - platform envelope covered by the measured data at 6-30 fps",
                  ["fps", "max trans m/s", "RPE trans mm there [n]", "max rot deg/s",
                   "RPE rot deg there [n]"],
                  note="Velocities are the largest per-frame motion with >= "
                       f"{tables.kMinSamplesPerCell} pure-motion pairs (translation study: rotation "
                       "< 0.3 deg; rotation study: translation < 3 mm) times the frame rate: beyond "
                       "them this study has no evidence, it does not mean tracking fails.")
    pure_t = pairs.select(pairs.gt_rot_deg < tables.kTransStudyMaxRotDeg)
    pure_r = pairs.select(pairs.gt_trans_mm < tables.kRotStudyMaxTransMm)

    def envelope(values, edges, sub):
        best = None
        for lo, hi in itertools.pairwise(edges):
            sel = tables.in_bin(values, lo, hi)
            if sel.sum() >= tables.kMinSamplesPerCell:
                best = (hi, CellStats.of(sub.select(sel)))
        return best

    t_env = envelope(pure_t.gt_trans_mm, tables.kTransStudyEdgesMm, pure_t)
    r_env = envelope(pure_r.gt_rot_deg, tables.kRotStudyEdgesDeg, pure_r)
    for fps in kPlatformFps:
        row = [f"{fps:g}"]
        row += ([f"{t_env[0] * fps / 1000:.3f}", f"{t_env[1].trans_text()} [{t_env[1].n}]"]
                if t_env else ["not enough data", "-"])
        row += ([f"{r_env[0] * fps:.1f}", f"{r_env[1].rot_text()} [{r_env[1].n}]"]
                if r_env else ["not enough data", "-"])
        table.rows.append(row)
    return table
