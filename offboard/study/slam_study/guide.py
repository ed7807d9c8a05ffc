"""Frame-rate guidance from the measured grid: `slam-study guide` and Table 4.21.

Given a platform's translational (m/s) and rotational (deg/s) velocity, the per-frame motion at a
frame rate f is v/f and w/f; the prediction is the measured RPE of the grid cell holding that
motion, with the cell's sample count per sequence, a 95 % confidence interval of its mean and its
90th percentile. The guide's grid is Table 4.20's plus a first row/column for motion below 1 mm /
0.1 deg (slow platforms) and coarser cells beyond 18 mm / 1.8 deg (slow frame rates). Motion above
the cell holding the largest measured motion (in translation or rotation) is "outside the
measured range"; a cell with
fewer than kMinSamplesPerCell pairs is "not enough data": neither is extrapolated.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slam_study import tables
from slam_study.pairs import PairTable
from slam_study.tables import CellStats, Table

# Beyond the thesis's 18 mm / 1.8 deg the guide keeps going with coarser cells, each edge ~1.4x the
# last (a cell's width grows with the motion, as the error's spread does): reduced-rate runs (k up
# to 8) reach ~130 mm per frame on fr1/xyz and ~29 deg on fr1/360 (a hand-held turn at up to
# 80 deg/s), and a slow frame rate or a fast turn is exactly what the guide is asked about. Cells
# above the measured motion stay empty: the guide answers "outside the measured motion" there.
kGuideTransEdgesMm = (
    (0.0,) + tables.kGridTransEdgesMm + (25.0, 35.0, 50.0, 70.0, 100.0, 140.0, 200.0)
)
kGuideRotEdgesDeg = (
    (0.0,) + tables.kGridRotEdgesDeg + (2.5, 3.5, 5.0, 7.0, 10.0, 14.0, 20.0, 28.0, 40.0)
)
# Candidate rates: what keeping every k-th frame of the Kinect's 30 fps gives, k = 1..8.
kCandidateFps = tuple(30.0 / k for k in range(1, 9))
# Table 4.21's rates: the thesis's platform estimate spans 6-30 fps.
kPlatformFps = (30.0, 20.0, 15.0, 10.0, 7.5, 6.0)
# Two-sided 95 % Student t quantiles by degrees of freedom (cells have >= 5 pairs: df >= 4);
# beyond 30 the Cornish-Fisher expansion below is within 0.001 of the exact value.
kT95 = {
    4: 2.776,
    5: 2.571,
    6: 2.447,
    7: 2.365,
    8: 2.306,
    9: 2.262,
    10: 2.228,
    11: 2.201,
    12: 2.179,
    13: 2.160,
    14: 2.145,
    15: 2.131,
    16: 2.120,
    17: 2.110,
    18: 2.101,
    19: 2.093,
    20: 2.086,
    21: 2.080,
    22: 2.074,
    23: 2.069,
    24: 2.064,
    25: 2.060,
    26: 2.056,
    27: 2.052,
    28: 2.048,
    29: 2.045,
    30: 2.042,
}
kZ95 = 1.959964
# The target of the guide's examples (docs/study.md) and of the demo's summary: about what our
# engine measures at 3.75-7.5 fps on fr1/xyz (RPE 10-12 mm), so the answer is a rate in the range.
kExampleTargetRpeMm = 8.0
# The flight's velocity the demo asks the guide about: this percentile of its 1 s windows (a
# hovering craft's mean would hide the legs that need the frame rate).
kFlightVelocityPercentile = 95.0


def t95(df: int) -> float:
    if df < 1:
        return float("nan")
    if df in kT95:
        return kT95[df]
    if df < min(kT95):
        return {1: 12.706, 2: 4.303, 3: 3.182}[df]
    z = kZ95
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


@dataclass(frozen=True)
class Prediction:
    fps: float
    trans_mm_per_frame: float
    rot_deg_per_frame: float
    cell: CellStats | None  # None: motion outside the measured range
    trans_bin: str
    rot_bin: str
    trans_ci_mm: tuple[float, float] = (float("nan"), float("nan"))  # 95 % CI of the mean
    trans_p90_mm: float = float("nan")
    by_dataset: tuple[tuple[str, int], ...] = ()  # pairs of the cell per sequence

    @property
    def enough(self) -> bool:
        return self.cell is not None and self.cell.n >= tables.kMinSamplesPerCell


def _locate(value: float, edges) -> int | None:
    for i, (lo, hi) in enumerate(itertools.pairwise(edges)):
        if lo <= value < hi:
            return i
    return None


def predict(
    pairs: PairTable,
    trans_m_per_s: float,
    rot_deg_per_s: float,
    fps_list=kCandidateFps,
    datasets: np.ndarray | None = None,
) -> list[Prediction]:
    """One prediction per rate. `datasets` (one name per pair) fills the per-sequence counts."""
    if not (np.isfinite(trans_m_per_s) and np.isfinite(rot_deg_per_s)):
        raise ValueError("velocities must be finite")
    if trans_m_per_s < 0 or rot_deg_per_s < 0:
        raise ValueError("velocities must be >= 0 (they are magnitudes)")
    # The measured range: up to the upper edge of the last cell holding any pair, per axis.
    top_t = _locate(float(pairs.gt_trans_mm.max()), kGuideTransEdgesMm) if len(pairs) else -1
    top_r = _locate(float(pairs.gt_rot_deg.max()), kGuideRotEdgesDeg) if len(pairs) else -1
    top_t = len(kGuideTransEdgesMm) if top_t is None else top_t
    top_r = len(kGuideRotEdgesDeg) if top_r is None else top_r
    out = []
    for fps in fps_list:
        t_mm = 1000.0 * trans_m_per_s / fps
        r_deg = rot_deg_per_s / fps
        ti = _locate(t_mm, kGuideTransEdgesMm)
        ri = _locate(r_deg, kGuideRotEdgesDeg)
        if ti is None or ri is None or ti > top_t or ri > top_r:
            out.append(Prediction(fps, t_mm, r_deg, None, "outside", "outside"))
            continue
        tlo, thi = kGuideTransEdgesMm[ti], kGuideTransEdgesMm[ti + 1]
        rlo, rhi = kGuideRotEdgesDeg[ri], kGuideRotEdgesDeg[ri + 1]
        sel = tables.in_bin(pairs.gt_trans_mm, tlo, thi) & tables.in_bin(pairs.gt_rot_deg, rlo, rhi)
        cell = CellStats.of(pairs.select(sel))
        ci, p90 = (float("nan"), float("nan")), float("nan")
        if cell.n >= 2:
            errs = pairs.rpe_trans_mm[sel]
            half = t95(cell.n - 1) * float(errs.std(ddof=1)) / np.sqrt(cell.n)
            ci = (cell.trans_mean_mm - half, cell.trans_mean_mm + half)
            p90 = float(np.percentile(errs, 90))
        by_ds: tuple[tuple[str, int], ...] = ()
        if datasets is not None:
            names, counts = np.unique(datasets[sel], return_counts=True)
            by_ds = tuple(
                sorted(
                    ((str(a), int(b)) for a, b in zip(names, counts, strict=False)),
                    key=lambda x: (-x[1], x[0]),
                )
            )
        out.append(
            Prediction(
                fps,
                t_mm,
                r_deg,
                cell,
                tables.bin_label(tlo, thi),
                tables.bin_label(rlo, rhi),
                ci,
                p90,
                by_ds,
            )
        )
    return out


def lowest_fps_meeting(preds: list[Prediction], target_rpe_mm: float) -> Prediction | None:
    """Going down from the highest candidate rate, the last rate whose cell has enough data and
    whose mean translational RPE is at or below the target with 95 % confidence (upper bound of
    the interval), stopping at the first rate that misses it (a noisy dip below a failing rate is
    not trusted: error grows with motion per frame). Rates without enough data are passed over."""
    best = None
    for p in sorted(preds, key=lambda p: -p.fps):
        if not p.enough:
            continue
        if p.trans_ci_mm[1] > target_rpe_mm:
            break
        best = p
    return best


def _datasets_text(p: Prediction) -> str:
    return ", ".join(f"{name} {n}" for name, n in p.by_dataset)


def guide_text(
    preds: list[Prediction],
    trans_m_per_s: float,
    rot_deg_per_s: float,
    target_rpe_mm: float | None,
    source: str,
    pairs: PairTable | None = None,
    provenance: str = "",
    recorded_speed: tuple[float, float] | None = None,
) -> str:
    """The guide's answer. recorded_speed: (m/s, deg/s) of the fastest second of the recordings
    the pairs come from; a faster request is said to be so."""
    lines = [
        f"Frame-to-frame error predicted for {trans_m_per_s:g} m/s and {rot_deg_per_s:g} "
        "deg/s at 30/k fps",
        f"Data: {source}"
        + (f", {len(pairs)} frame pairs" if pairs is not None else "")
        + (f"; {provenance}" if provenance else ""),
    ]
    if pairs is not None and len(pairs):
        lines.append(
            f"Measured per-frame motion reaches {pairs.gt_trans_mm.max():.1f} mm and "
            f"{pairs.gt_rot_deg.max():.2f} deg; the guide answers within its cells (up to "
            f"{kGuideTransEdgesMm[-1]:g} mm, {kGuideRotEdgesDeg[-1]:g} deg)"
        )
        lines.append("and never beyond the last cell holding a measured pair.")
    if recorded_speed is not None:
        lines.append(
            f"The recordings moved at up to {recorded_speed[0]:.2f} m/s and "
            f"{recorded_speed[1]:.1f} deg/s (fastest 1 s); larger per-frame motion comes "
            "from dropping frames."
        )
    lines += [
        f"A cell needs >= {tables.kMinSamplesPerCell} pairs. Interval: 95 % confidence "
        "interval of the cell's mean (Student t;",
        "optimistic, as consecutive pairs are correlated). p90: 90 % of the cell's pairs "
        "had less error.",
        "",
        (
            f"{'fps':>6} {'mm/frame':>9} {'deg/frame':>9}  {'cell mm x deg':>17}  {'n':>4}  "
            f"{'trans mm: mean [95 % CI]':>25}  {'p90':>6}  {'rot deg':>7}  pairs per sequence"
        ),
    ]
    for p in preds:
        head = f"{p.fps:6.2f} {p.trans_mm_per_frame:9.2f} {p.rot_deg_per_frame:9.3f}  "
        if p.cell is None:
            lines.append(head + f"{'-':>17}  {'-':>4}  outside the measured motion: no prediction")
        elif not p.enough:
            lines.append(
                head + f"{p.trans_bin + ' x ' + p.rot_bin:>17}  {p.cell.n:4d}  "
                f"{'not enough data':>25}  {'':>6}  {'':>7}  {_datasets_text(p)}"
            )
        else:
            interval = (
                f"{p.cell.trans_mean_mm:.2f} [{p.trans_ci_mm[0]:.2f}, {p.trans_ci_mm[1]:.2f}]"
            )
            lines.append(
                head + f"{p.trans_bin + ' x ' + p.rot_bin:>17}  {p.cell.n:4d}  "
                f"{interval:>25}  {p.trans_p90_mm:6.2f}  {p.cell.rot_mean_deg:7.3f}  "
                f"{_datasets_text(p)}"
            )
    lines.append("")
    if recorded_speed is not None and (
        trans_m_per_s > recorded_speed[0] or rot_deg_per_s > recorded_speed[1]
    ):
        lines.append(
            f"{trans_m_per_s:g} m/s, {rot_deg_per_s:g} deg/s is faster than any recording "
            "the data rest on: the per-frame motion may be measured (frames dropped), the "
            "motion blur of that speed is not."
        )
    outside = [p for p in preds if p.cell is None]
    if outside and len(outside) == len(preds):
        lines.append(
            "The requested velocity lies outside what was measured at every candidate "
            "rate: no prediction (the guide does not extrapolate)."
        )
    elif outside:
        lines.append(
            "The requested velocity lies outside what was measured at "
            + ", ".join(f"{p.fps:.2f}" for p in outside)
            + " fps: no prediction there (the guide does not extrapolate)."
        )
    thin = [p for p in preds if p.cell is not None and not p.enough]
    if thin:
        lines.append("Not enough data at " + ", ".join(f"{p.fps:.2f}" for p in thin) + " fps.")
    if target_rpe_mm is not None:
        best = lowest_fps_meeting(preds, target_rpe_mm)
        if best is None:
            lines.append(
                f"No candidate rate is known to meet {target_rpe_mm:g} mm per frame "
                "(either the error is higher or the grid has not enough data there)."
            )
        else:
            lines.append(
                f"Lowest frame rate meeting {target_rpe_mm:g} mm per frame: "
                f"{best.fps:.2f} fps (mean {best.cell.trans_mean_mm:.2f} mm, 95 % CI "
                f"up to {best.trans_ci_mm[1]:.2f} mm, n={best.cell.n})."
            )
            unknown_below = [p for p in preds if p.fps < best.fps and not p.enough]
            if unknown_below:
                lines.append(
                    "Lower rates have not enough data to say: "
                    + ", ".join(f"{p.fps:.2f}" for p in unknown_below)
                    + " fps."
                )
    return "\n".join(lines) + "\n"


def flight_summary(
    groundtruth_tum: Path,
    fps_flown: float,
    target_rpe_mm: float = kExampleTargetRpeMm,
    pairs: PairTable | None = None,
    source: str = "",
) -> str:
    """One paragraph for a flown trajectory (e.g. the HIL demo's camera truth, TUM format): its
    velocity (kFlightVelocityPercentile of the 1 s windows, thesis Table 3.3's definition), the
    error the guide predicts at the rate flown, and the lowest rate predicted to meet the target.
    Default pairs: the shipped table's default source."""
    from slam_study import shipped, velocity
    from slam_study.tum import read_trajectory

    if pairs is None:
        table = shipped.read()
        source = table.default_source()
        pairs = table.pairs(source)[0]

    gt = read_trajectory(groundtruth_tum)
    v, w, _ = velocity.window_velocities(gt, gt.stamps_s[0], gt.stamps_s[-1])
    if v.size == 0:
        return f"frame-rate guide: {groundtruth_tum} is too short to measure a velocity"
    v_p, w_p = (float(np.percentile(x, kFlightVelocityPercentile)) for x in (v, w))
    preds = predict(pairs, v_p, w_p, fps_list=sorted({fps_flown, *kCandidateFps}, reverse=True))
    flown = next(p for p in preds if p.fps == fps_flown)
    if flown.cell is None:
        at_flown = "outside the measured motion (no prediction)"
    elif not flown.enough:
        at_flown = f"not enough data (n={flown.cell.n})"
    else:
        at_flown = (
            f"{flown.cell.trans_mean_mm:.1f} mm per frame [95 % CI "
            f"{flown.trans_ci_mm[0]:.1f}, {flown.trans_ci_mm[1]:.1f}], n={flown.cell.n}"
        )
    best = lowest_fps_meeting(preds, target_rpe_mm)
    rec = (
        f"lowest rate meeting {target_rpe_mm:g} mm: {best.fps:.2f} fps"
        if best
        else f"no rate is known to meet {target_rpe_mm:g} mm"
    )
    return (
        f"frame-rate guide ({source}): the camera moved {v_p:.2f} m/s, {w_p:.1f} deg/s "
        f"(p{kFlightVelocityPercentile:g} of 1 s windows; mean {v.mean():.2f} m/s, "
        f"{w.mean():.1f} deg/s); at the {fps_flown:g} fps flown: {at_flown}; {rec}. "
        f"Details: slam-study guide --trans-vel {v_p:.2f} --rot-vel {w_p:.1f} "
        f"--target-rpe-mm {target_rpe_mm:g}"
    )


def platform_table(pairs: PairTable) -> Table:
    """Table 4.21: at each rate, the fastest platform motion the measured data covers (upper edge
    of the largest pure-motion bin with enough pairs, times the rate) and the error measured
    there."""
    table = Table(
        "table_4_21_platform",
        "Table 4.21 - platform envelope covered by the measured data at 6-30 fps",
        [
            "fps",
            "max trans m/s",
            "RPE trans mm there [n]",
            "max rot deg/s",
            "RPE rot deg there [n]",
        ],
        note="Velocities are the largest per-frame motion with >= "
        f"{tables.kMinSamplesPerCell} pure-motion pairs (translation study: rotation "
        "< 0.3 deg; rotation study: translation < 3 mm) times the frame rate: beyond "
        "them this study has no evidence, it does not mean tracking fails.",
    )
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
        row += (
            [f"{t_env[0] * fps / 1000:.3f}", f"{t_env[1].trans_text()} [{t_env[1].n}]"]
            if t_env
            else ["not enough data", "-"]
        )
        row += (
            [f"{r_env[0] * fps:.1f}", f"{r_env[1].rot_text()} [{r_env[1].n}]"]
            if r_env
            else ["not enough data", "-"]
        )
        table.rows.append(row)
    return table
