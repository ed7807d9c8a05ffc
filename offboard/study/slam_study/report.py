"""The report: every table as Markdown (report.md) and CSV (tables/*.csv), plots as PNG (plots/),
the per-pair records (pairs.csv, read back by `slam-study guide`).

Inputs: the sweep's run folders under OUT/runs (see sweep.py) and optional reference estimates
(a trajectory by another system on a dataset, e.g. RGBD-SLAM on fr1/xyz), each a separate source.
Errors are recomputed here from trajectory.tum and the dataset's ground truth for every run, so all
sources are scored by one definition (pairs.py); metrics.json supplies keyframes and stage times.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slam_study import guide, metrics, plots, tables, thesis, velocity
from slam_study.pairs import AteResult, PairTable, absolute_trajectory_error, motion_pairs, rmse
from slam_study.tum import Dataset, Trajectory, TumFormatError, read_trajectory

kPairColumns = [
    "source",
    "dataset",
    "features",
    "backend",
    "k",
    "stamp_s",
    "dt_s",
    "gt_trans_mm",
    "gt_rot_deg",
    "share_x",
    "share_y",
    "share_z",
    "share_roll",
    "share_pitch",
    "share_yaw",
    "rpe_trans_mm",
    "rpe_rot_deg",
]
# The per-pair study takes one back-end per detector: frame-to-frame error is the front end's, and
# pooling vo/llc/glc would count the same frame pairs three times. vo is the plain front end.
kGridBackend = "vo"
kSweepSourcePrefix = "slam-eval "


@dataclass
class Run:
    dataset: str
    features: str
    backend: str
    k: int
    status: str
    reason: str
    wall_s: float | None
    trajectory: Trajectory | None = None
    metrics: dict = field(default_factory=dict)
    pairs: PairTable | None = None
    ate: AteResult | None = None

    @property
    def config(self) -> str:
        return f"{self.features}-{self.backend}"


@dataclass
class Source:
    name: str
    pairs: PairTable
    rows: list[tuple[str, str, str, int, PairTable]]  # (dataset, features, backend, k, pairs)


def load_runs(out: Path, datasets: dict[str, Dataset], warn) -> list[Run]:
    runs = []
    for result_path in sorted((out / "runs").glob("*/*/result.json")):
        try:
            meta = json.loads(result_path.read_text())
            job = meta["job"]
        except (OSError, ValueError, KeyError) as err:
            warn(f"skipping {result_path}: unreadable ({err})")
            continue
        run = Run(
            Path(job["dataset"]).name,
            job["features"],
            job["backend"],
            int(job["k"]),
            meta.get("status", "failed"),
            meta.get("reason", ""),
            meta.get("wall_s"),
        )
        run_dir = result_path.parent
        run.metrics = metrics.load(run_dir / "metrics.json")
        if run.status == "ok":
            dataset = _dataset(job["dataset"], datasets, warn)
            try:
                run.trajectory = read_trajectory(run_dir / "trajectory.tum")
            except TumFormatError as err:
                run.status, run.reason = "failed", f"unreadable trajectory: {err}"
            if dataset is not None and run.trajectory is not None:
                run.pairs = motion_pairs(dataset.groundtruth, run.trajectory)
                run.ate = absolute_trajectory_error(dataset.groundtruth, run.trajectory)
        runs.append(run)
    return runs


def _dataset(path: str, cache: dict[str, Dataset], warn) -> Dataset | None:
    name = Path(path).name
    if name not in cache:
        try:
            cache[name] = Dataset.load(path)
        except TumFormatError as err:
            warn(f"dataset {path} unavailable, its runs are not scored: {err}")
            return None
    return cache[name]


def _config_table(key: str, title: str, runs: list[Run], cell, note: str = "") -> tables.Table:
    configs = sorted({r.config for r in runs})
    table = tables.Table(key, title, ["dataset", "k"] + configs, note=note)
    by_key = {(r.dataset, r.k, r.config): r for r in runs}
    for ds, k in sorted({(r.dataset, r.k) for r in runs}):
        row = [ds, str(k)]
        for cfg in configs:
            run = by_key.get((ds, k, cfg))
            row.append("-" if run is None else ("failed" if run.status != "ok" else cell(run)))
        table.rows.append(row)
    return table


def run_tables(runs: list[Run]) -> list[tables.Table]:
    """Tables 4.5/4.8/4.9 (RPE), 4.10 (ATE), 4.7 (keyframes), 4.12/4.13 (time per stage)."""

    def rpe(run: Run) -> str:
        if run.pairs is None or len(run.pairs) == 0:
            return "no pairs"
        return f"{rmse(run.pairs.rpe_trans_mm):.2f} / {rmse(run.pairs.rpe_rot_deg):.3f}"

    def ate(run: Run) -> str:
        return "-" if run.ate is None else f"{1000 * run.ate.rmse_m:.1f}"

    def keyframes(run: Run) -> str:
        kf = metrics.count(run.metrics, "keyframe")
        loops = metrics.count(run.metrics, "loop")
        frames = len(run.trajectory) if run.trajectory is not None else 0
        lost = metrics.count(run.metrics, "lost")
        return (
            f"{'-' if kf is None else kf} / {frames}"
            + ("" if loops is None else f" ({loops} loops)")
            + ("" if not lost else f", {lost} lost")
        )

    out = [
        _config_table(
            "table_4_5_rpe",
            "Tables 4.5 / 4.8 / 4.9 - RPE RMSE per frame pair, translational mm / rotational deg",
            runs,
            rpe,
            note="Consecutive pairs of the run (k frames apart in the recording); "
            "recomputed from trajectory.tum against groundtruth.txt.",
        ),
        _config_table("table_4_10_ate", "Table 4.10 - ATE RMSE (mm), rigid alignment", runs, ate),
        _config_table(
            "table_4_7_keyframes",
            "Table 4.7 - keyframes / poses in trajectory "
            "(loop closures, frames with tracking lost)",
            runs,
            keyframes,
            note="Keyframes and loop closures as reported in metrics.json.",
        ),
    ]
    stage_names = sorted({s for r in runs for s in metrics.stages(r.metrics)})
    timing = tables.Table(
        "table_4_12_stage_times",
        "Tables 4.12 / 4.13 - time per stage, ms "
        "mean / median / p95 (k = 1 runs, from metrics.json)",
        ["dataset", "config"] + stage_names,
    )
    for run in sorted(
        (r for r in runs if r.k == 1 and r.status == "ok"), key=lambda r: (r.dataset, r.config)
    ):
        st = metrics.stages(run.metrics)
        row = [run.dataset, run.config]
        for name in stage_names:
            s = st.get(name)
            row.append(
                "-"
                if s is None
                else " / ".join(
                    f"{s[k_]:.1f}" if k_ in s else "-" for k_ in ("mean_ms", "median_ms", "p95_ms")
                )
            )
        timing.rows.append(row)
    out.append(timing)
    status = tables.Table(
        "run_status", "Run status (failed runs and why)", ["dataset", "config", "k", "reason"]
    )
    for run in runs:
        if run.status != "ok":
            status.rows.append([run.dataset, run.config, str(run.k), run.reason])
    out.append(status)
    return out


def per_config_translation(runs: list[Run]) -> tables.Table:
    """Translation-study RPE per configuration: the detectors/back-ends side by side."""
    edges = tables.kTransStudyEdgesMm
    table = tables.Table(
        "per_config_translation",
        "Translation study per configuration: RPE trans mm mean [n], rotation < 0.3 deg",
        ["config"] + [tables.bin_label(a, b) for a, b in itertools.pairwise(edges)],
    )
    for cfg in sorted({r.config for r in runs if r.pairs is not None}):
        pooled = PairTable.concat(
            [r.pairs for r in runs if r.config == cfg and r.pairs is not None]
        )
        pure = pooled.select(pooled.gt_rot_deg < tables.kTransStudyMaxRotDeg)
        row = [cfg]
        for lo, hi in itertools.pairwise(edges):
            c = tables.CellStats.of(pure.select(tables.in_bin(pure.gt_trans_mm, lo, hi)))
            row.append("-" if c.n == 0 else f"{c.trans_mean_mm:.2f} [{c.n}]")
        table.rows.append(row)
    return table


def _verdict_ratio(ours: float, theirs: float, n: int) -> str:
    """'agrees' when our value is within a factor of 2 of the thesis's (the same order of effect;
    datasets, detectors and the engine differ, so closer agreement is not expected)."""
    if n < tables.kMinSamplesPerCell or math.isnan(ours):
        return f"not enough data (n={n})"
    ratio = ours / theirs if theirs else float("inf")
    return "agrees (within x2)" if 0.5 <= ratio <= 2.0 else f"differs (x{ratio:.2f})"


def thesis_comparison(pairs: PairTable) -> tables.Table:
    """Our measurement beside each published number the project has (thesis.py)."""
    t = tables.Table(
        "thesis_comparison",
        "Ours beside the thesis's published numbers",
        ["finding", "selection", "ours", "n", "thesis (published)", "verdict"],
        note="Thesis column: only the values quoted in the study issue; "
        "everything else in the thesis is 'not quoted' here.",
    )
    pure_r = pairs.select(
        (pairs.gt_trans_mm < tables.kRotStudyMaxTransMm) & tables.in_bin(pairs.gt_rot_deg, 0.8, 1.2)
    )
    c = tables.CellStats.of(pure_r)
    t.rows.append(
        [
            "1 deg/frame rotation -> trans RPE",
            "trans < 3 mm, rot 0.8-1.2 deg",
            tables._fmt(c.trans_mean_mm) + " mm",
            str(c.n),
            f"~{thesis.kRotation1DegTransRpeMm:g} mm",
            _verdict_ratio(c.trans_mean_mm, thesis.kRotation1DegTransRpeMm, c.n),
        ]
    )
    frac = c.rot_mean_deg / c.motion_rot_mean_deg if c.n else float("nan")
    t.rows.append(
        [
            "1 deg/frame rotation -> rot error",
            "same",
            tables._pct(c.rot_mean_deg, c.motion_rot_mean_deg),
            str(c.n),
            f"~{100 * thesis.kRotation1DegRotRpeFraction:.0f} %",
            _verdict_ratio(frac, thesis.kRotation1DegRotRpeFraction, c.n),
        ]
    )
    pure_t = pairs.select(
        (pairs.gt_rot_deg < tables.kTransStudyMaxRotDeg)
        & tables.in_bin(pairs.gt_trans_mm, 8.0, 12.0)
    )
    c = tables.CellStats.of(pure_t)
    frac = c.trans_mean_mm / c.motion_trans_mean_mm if c.n else float("nan")
    t.rows.append(
        [
            "10 mm/frame translation -> trans error",
            "rot < 0.3 deg, trans 8-12 mm",
            tables._pct(c.trans_mean_mm, c.motion_trans_mean_mm),
            str(c.n),
            f"~{100 * thesis.kTranslation10MmTransRpeFraction:.0f} %",
            _verdict_ratio(frac, thesis.kTranslation10MmTransRpeFraction, c.n),
        ]
    )
    t.rows.append(
        [
            "10 mm/frame translation -> rot RPE",
            "same",
            tables._fmt(c.rot_mean_deg, 3) + " deg",
            str(c.n),
            f"{thesis.kTranslation10MmRotRpeDeg:g} deg",
            _verdict_ratio(c.rot_mean_deg, thesis.kTranslation10MmRotRpeDeg, c.n),
        ]
    )
    corner = thesis.kGridCorner
    sel = tables.in_bin(pairs.gt_trans_mm, *corner["trans_bin_mm"]) & tables.in_bin(
        pairs.gt_rot_deg, *corner["rot_bin_deg"]
    )
    c = tables.CellStats.of(pairs.select(sel))
    t.rows.append(
        [
            "18 mm + 1.8 deg/frame (grid corner)",
            "trans 16-18 mm, rot 1.6-1.8 deg",
            f"{tables._fmt(c.trans_mean_mm)} mm / {tables._fmt(c.rot_mean_deg, 3)} deg",
            str(c.n),
            f"{corner['rpe_trans_mm']:.2f} mm / {corner['rpe_rot_deg']:.2f} deg",
            _verdict_ratio(c.trans_mean_mm, corner["rpe_trans_mm"], c.n),
        ]
    )
    # Axis findings: error per unit motion, single-axis pairs.
    t.rows.append(_axis_row(pairs, rotation=False))
    t.rows.append(_axis_row(pairs, rotation=True))
    t.rows.extend(_fit_rows(pairs))
    return t


# A least-squares fit needs clearly more pairs than its 4 coefficients to mean anything.
kMinPairsForFit = 20


def effect_fit(pairs: PairTable, interaction: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
    """Least squares over every pair: rpe_trans_mm = a + b*t_mm + c*r_deg (+ d*t_mm*r_deg when
    interaction). Returns (coefficients, standard errors) or None with too few pairs. From the
    additive fit, b and c are the marginal costs of translation and rotation (thesis: ~0.45 mm/mm,
    ~4 mm/deg); in the full fit d > 0 means the two compound (the 'multiplicative' finding)."""
    n = len(pairs)
    cols = [np.ones(n), pairs.gt_trans_mm, pairs.gt_rot_deg]
    if interaction:
        cols.append(pairs.gt_trans_mm * pairs.gt_rot_deg)
    if n < kMinPairsForFit:
        return None
    x = np.column_stack(cols)
    coef, _, rank, _ = np.linalg.lstsq(x, pairs.rpe_trans_mm, rcond=None)
    if rank < x.shape[1]:
        return None
    resid = pairs.rpe_trans_mm - x @ coef
    sigma2 = float(resid @ resid) / (n - x.shape[1])
    se = np.sqrt(np.diag(sigma2 * np.linalg.inv(x.T @ x)))
    return coef, se


def _fit_rows(pairs: PairTable) -> list[list[str]]:
    additive = effect_fit(pairs, interaction=False)
    full = effect_fit(pairs, interaction=True)
    sel_add = "all pairs, trans RPE = a + b t + c r"
    sel_full = "all pairs, trans RPE = a + b t + c r + d t r"
    n = str(len(pairs))
    if additive is None or full is None:
        return [["fits over all pairs", sel_full, "-", n, "-", "not enough data"]]
    (_, b, c), (_, sb, sc) = additive
    (a4, b4, c4, d), (_, _, _, sd) = full
    per_deg = thesis.kRotation1DegTransRpeMm
    per_mm = thesis.kTranslation10MmTransRpeFraction

    def ratio_verdict(ours: float, theirs: float) -> str:
        return (
            "agrees (within x2)" if 0.5 <= ours / theirs <= 2 else f"differs (x{ours / theirs:.2f})"
        )

    corner = a4 + b4 * 17.0 + c4 * 1.7 + d * 17.0 * 1.7
    return [
        [
            "marginal cost of rotation (fit c)",
            sel_add,
            f"{c:.2f} ± {sc:.2f} mm per deg",
            n,
            f"~{per_deg:g} mm per deg",
            ratio_verdict(c, per_deg),
        ],
        [
            "marginal cost of translation (fit b)",
            sel_add,
            f"{b:.3f} ± {sb:.3f} mm per mm",
            n,
            "45 % at 10 mm (0.45 mm per mm if proportional)",
            ratio_verdict(b, per_mm),
        ],
        [
            "rotation hurts more: 1 deg costs as much as c/b mm of translation",
            sel_add,
            f"{c / b:.1f} mm" if b > 0 else "b <= 0 (translation adds no error)",
            n,
            f"~{per_deg / per_mm:.1f} mm (derived: 4 mm per deg / 0.45 mm per mm)",
            "agrees (rotation costs more)" if (b <= 0 < c or (b > 0 and c / b > 1)) else "differs",
        ],
        [
            "compounding (fit d; > 0 = super-additive)",
            sel_full,
            f"{d:.3f} ± {sd:.3f} mm per mm·deg",
            n,
            "multiplicative (no coefficient quoted)",
            "agrees" if d - 2 * sd > 0 else ("differs" if d + 2 * sd < 0 else "inconclusive (±2σ)"),
        ],
        [
            "full fit evaluated at 17 mm + 1.7 deg",
            sel_full,
            f"{corner:.2f} mm",
            n,
            f"{thesis.kGridCorner['rpe_trans_mm']:.2f} mm (18 mm + 1.8 deg)",
            ratio_verdict(corner, thesis.kGridCorner["rpe_trans_mm"])
            + " (extrapolated where the grid is thin)",
        ],
    ]


def _axis_row(pairs: PairTable, rotation: bool) -> list[str]:
    if rotation:
        pure = pairs.select(
            (pairs.gt_trans_mm < tables.kRotStudyMaxTransMm)
            & (pairs.gt_rot_deg >= tables.kRotStudyEdgesDeg[0])
        )
        shares, thr, names, cheap = (
            pure.rot_share,
            tables.kRotSingleAxisShare,
            ("roll", "pitch", "yaw"),
            0,
        )
        ratio = pure.rpe_rot_deg / np.maximum(pure.gt_rot_deg, 1e-9)
        finding, unit = "roll costs less (rot RPE / rotation)", "single-axis > 85 %"
    else:
        pure = pairs.select(
            (pairs.gt_rot_deg < tables.kTransStudyMaxRotDeg)
            & (pairs.gt_trans_mm >= tables.kTransStudyEdgesMm[0])
        )
        shares, thr, names, cheap = (
            pure.trans_share,
            tables.kTransSingleAxisShare,
            ("x", "y", "z"),
            2,
        )
        ratio = pure.rpe_trans_mm / np.maximum(pure.gt_trans_mm, 1e-9)
        finding, unit = "z-translation costs less (trans RPE / translation)", "single-axis > 80 %"
    parts, ns, means = [], [], []
    for i, name in enumerate(names):
        sel = shares[:, i] > thr
        n = int(sel.sum())
        m = float(ratio[sel].mean()) if n else float("nan")
        parts.append(f"{name} {tables._fmt(100 * m, 0)} %")
        ns.append(f"{name} {n}")
        means.append((m, n))
    others = [means[i] for i in range(3) if i != cheap]
    if means[cheap][1] < tables.kMinSamplesPerCell or any(
        n < tables.kMinSamplesPerCell for _, n in others
    ):
        verdict = "not enough data"
    else:
        verdict = "agrees" if means[cheap][0] < min(m for m, _ in others) else "differs"
    return [finding, unit, ", ".join(parts), ", ".join(ns), "cheaper (no value quoted)", verdict]


def write_pairs_csv(path: Path, sources: list[Source]) -> None:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(kPairColumns)
        for src in sources:
            for ds, feat, backend, k, p in src.rows:
                for i in range(len(p)):
                    writer.writerow(
                        [
                            src.name,
                            ds,
                            feat,
                            backend,
                            k,
                            f"{p.stamp_s[i]:.6f}",
                            f"{p.dt_s[i]:.6f}",
                            f"{p.gt_trans_mm[i]:.4f}",
                            f"{p.gt_rot_deg[i]:.5f}",
                            *(f"{v:.4f}" for v in p.trans_share[i]),
                            *(f"{v:.4f}" for v in p.rot_share[i]),
                            f"{p.rpe_trans_mm[i]:.4f}",
                            f"{p.rpe_rot_deg[i]:.5f}",
                        ]
                    )


def read_pairs_csv(path: str | Path, source: str | None = None) -> tuple[PairTable, str, list[str]]:
    """Pairs of one source from pairs.csv (default: the one with the most pairs). Returns the
    pairs, the source used and the list of sources in the file."""
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as err:
        raise TumFormatError(f"{path}: cannot read ({err.strerror})") from err
    names = list(dict.fromkeys(r["source"] for r in rows))
    if not names:
        raise TumFormatError(f"{path}: no pairs")
    if source is None:
        source = default_source(rows)
    if source not in names:
        raise TumFormatError(f"{path}: no source '{source}'; sources: {names}")
    sel = [r for r in rows if r["source"] == source]
    try:
        col = {c: np.array([float(r[c]) for r in sel]) for c in kPairColumns[5:]}
    except (KeyError, ValueError) as err:
        raise TumFormatError(f"{path}: malformed pairs file ({err})") from err
    pairs = PairTable(
        col["stamp_s"],
        col["dt_s"],
        col["gt_trans_mm"],
        col["gt_rot_deg"],
        np.stack([col["share_x"], col["share_y"], col["share_z"]], axis=1),
        np.stack([col["share_roll"], col["share_pitch"], col["share_yaw"]], axis=1),
        col["rpe_trans_mm"],
        col["rpe_rot_deg"],
    )
    return pairs, source, names


def read_pairs_datasets(path: str | Path, source: str) -> np.ndarray:
    """The dataset name of each pair of `source` in pairs.csv, in read_pairs_csv's order."""
    with Path(path).open(newline="") as fh:
        return np.array([r["dataset"] for r in csv.DictReader(fh) if r["source"] == source])


def default_source(rows: list[dict]) -> str:
    """The slam-eval source with the most pairs (its runs cover the reduced frame rates), else the
    source with the most pairs; ties by name."""
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["source"]] = counts.get(r["source"], 0) + 1
    own = [name for name in counts if name.startswith(kSweepSourcePrefix)]
    return min(own or counts, key=lambda name: (-counts[name], name))


def _slug(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name).strip("_").lower()


def pair_sections(src: Source, out: Path) -> list[str]:
    """Markdown for one source: Tables 4.14-4.21, thesis comparison, plots; CSVs written."""
    slug = _slug(src.name)
    p = src.pairs
    md = [
        f"## Per-pair study: {src.name}",
        "",
        (
            f"{len(p)} consecutive frame pairs. Motion and axis shares in the camera frame of the "
            "first frame of each pair (x right, y down, z optical axis; roll about z, "
            "pitch about x, yaw about y). "
            f"Cells with fewer than {tables.kMinSamplesPerCell} pairs are marked thin."
        ),
        "",
    ]
    t414, t415 = tables.translation_study(p)
    t417, t418 = tables.rotation_study(p)
    t420a, t420b, cells = tables.joint_grid(p)
    t416, t419 = tables.velocity_tables(p)
    t421 = guide.platform_table(p)
    quoted = "Thesis (published) values for this table: "
    t414.note = (
        quoted + "~45 % translational error and 0.2 deg at 10 mm per frame; other cells not quoted."
    )
    t417.note = (
        quoted + "~4 mm translational error and ~20 % rotational error at 1 deg per "
        "frame; other cells not quoted."
    )
    t420a.note = (
        quoted + f"cell 16-18 mm x 1.6-1.8 deg (18 mm + 1.8 deg): "
        f"{thesis.kGridCorner['rpe_trans_mm']:.2f} mm / "
        f"{thesis.kGridCorner['rpe_rot_deg']:.2f} deg; other cells not quoted."
    )
    for table in (t415, t416, t418, t419, t420b, t421):
        table.note = (table.note + " " if table.note else "") + "Thesis values: not quoted."
    comparison = thesis_comparison(p)
    for table in (comparison, t414, t415, t416, t417, t418, t419, t420a, t420b, t421):
        (out / "tables" / f"{slug}__{table.key}.csv").write_text(table.csv())
        md.append(table.markdown())
    for fname, fn in (
        (
            f"{slug}_error_vs_translation.png",
            lambda path: plots.error_vs_motion(p, path, src.name, rotation=False),
        ),
        (
            f"{slug}_error_vs_rotation.png",
            lambda path: plots.error_vs_motion(p, path, src.name, rotation=True),
        ),
        (
            f"{slug}_grid.png",
            lambda path: plots.grid_heatmap(cells, path, f"Table 4.20 grid: {src.name}"),
        ),
    ):
        fn(out / "plots" / fname)
        md += [f"![{fname}](plots/{fname})", ""]
    return md


def build(out: Path, references: list[tuple[str, str]], ks_for_rates: list[int], warn) -> Path:
    """Writes OUT/report.md (+ tables/, plots/, pairs.csv) from OUT/runs and the references
    [(dataset_dir, trajectory_file)]. Returns the report path."""
    out.mkdir(parents=True, exist_ok=True)
    for sub, pattern in (("tables", "*.csv"), ("plots", "*.png")):
        (out / sub).mkdir(exist_ok=True)
        for stale in (out / sub).glob(pattern):  # from an earlier report with other sources
            stale.unlink()
    datasets: dict[str, Dataset] = {}
    runs = load_runs(out, datasets, warn)
    sources: list[Source] = []
    ok_runs = [r for r in runs if r.pairs is not None]
    backends = {r.backend for r in ok_runs}
    grid_backend = kGridBackend if kGridBackend in backends else min(backends, default=None)
    for feat in sorted({r.features for r in ok_runs if r.backend == grid_backend}):
        chosen = [r for r in ok_runs if r.features == feat and r.backend == grid_backend]
        rows = [(r.dataset, r.features, r.backend, r.k, r.pairs) for r in chosen]
        sources.append(
            Source(
                f"{kSweepSourcePrefix}{feat}-{grid_backend} (all datasets and k)",
                PairTable.concat([r.pairs for r in chosen]),
                rows,
            )
        )
    ref_trajs: dict[str, dict[str, Trajectory]] = {}
    for ds_dir, traj_file in references:
        ds = _dataset(str(Path(ds_dir).resolve()), datasets, warn)
        if ds is None:
            continue
        est = read_trajectory(traj_file)
        name = f"peer {Path(traj_file).stem} on {ds.name}"
        p = motion_pairs(ds.groundtruth, est)
        sources.append(Source(name, p, [(ds.name, "peer", Path(traj_file).stem, 1, p)]))
        ate = absolute_trajectory_error(ds.groundtruth, est)
        if ate is not None:
            ref_trajs.setdefault(ds.name, {})[f"peer {Path(traj_file).stem}"] = ate.aligned_est

    md = [
        "# Spatial-velocity study (thesis Chapter 4) on TUM RGB-D data",
        "",
        (
            "Generated by `slam-study` (offboard/study/slam_study); method and closing note in "
            "docs/study.md. Data: TUM RGB-D benchmark (Sturm et al., IROS 2012, CC BY 4.0)."
        ),
        "",
    ]
    sweep_record = out / "sweep.json"
    if sweep_record.is_file():
        rec = json.loads(sweep_record.read_text())
        md += ["## Sweep", "", "```", json.dumps(rec, indent=1), "```", ""]
    n_ok = sum(r.status == "ok" for r in runs)
    md += [
        (
            f"Runs found: {len(runs)} ({n_ok} ok, {len(runs) - n_ok} failed). "
            f"Sources of frame pairs: {', '.join(s.name for s in sources) or 'none'}."
        ),
        "",
    ]

    md += ["## Datasets at reduced frame rates (Table 3.4)", ""]
    for _name, ds in sorted(datasets.items()):
        table = velocity.rate_table(ds, ks_for_rates)
        (out / "tables" / f"{table.key}.csv").write_text(table.csv())
        md.append(table.markdown())
    t33 = tables.Table(
        "table_3_3_thesis",
        "Thesis Table 3.3 (published; full sequences, ours are excerpts)",
        ["sequence", "duration s", "frames", "trans m/s", "rot deg/s"],
    )
    for seq, v in thesis.kTable33.items():
        t33.rows.append(
            [
                seq,
                f"{v['duration_s']}",
                f"{v['frames']}",
                f"{v['trans_m_per_s']}",
                f"{v['rot_deg_per_s']}",
            ]
        )
    md.append(t33.markdown())

    if runs:
        md += ["## Per sequence x detector x back-end", ""]
        for table in run_tables(runs) + [per_config_translation(runs)]:
            (out / "tables" / f"{table.key}.csv").write_text(table.csv())
            md.append(table.markdown())
    for src in sources:
        md += pair_sections(src, out)

    md += ["## Trajectories (top-down, ATE-aligned, k = 1)", ""]
    for name, ds in sorted(datasets.items()):
        estimates = {
            f"{r.config}": r.ate.aligned_est
            for r in runs
            if r.dataset == name and r.k == 1 and r.ate is not None
        }
        estimates.update(ref_trajs.get(name, {}))
        if not estimates:
            continue
        fname = f"traj_{_slug(name)}.png"
        start_s = min(t.stamps_s[0] for t in estimates.values())
        end_s = max(t.stamps_s[-1] for t in estimates.values())
        in_span = (ds.groundtruth.stamps_s >= start_s) & (ds.groundtruth.stamps_s <= end_s)
        gt = ds.groundtruth.subset(np.where(in_span)[0])
        plots.trajectories_top_down(
            gt, estimates, out / "plots" / fname, f"{name}: ground truth vs estimates"
        )
        md += [f"![{fname}](plots/{fname})", ""]
    write_pairs_csv(out / "pairs.csv", sources)
    report = out / "report.md"
    report.write_text("\n".join(md) + "\n")
    return report
