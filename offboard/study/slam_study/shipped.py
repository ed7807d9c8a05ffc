"""The guide's table shipped in the repository: `data/guide_pairs.csv`.

`slam-study guide` needs measured per-frame-pair errors; a sweep takes minutes and data a new user
may not have, so the per-pair samples of the sweep's front-end sources (`<detector>-vo`, the ones
the guide reads, docs/study.md) are kept in the repository as a small text file:

    # key: value                          provenance (see kMetaKeys), one line each
    source,dataset,k,stamp_s,dt_s,gt_trans_mm,gt_rot_deg,rpe_trans_mm,rpe_rot_deg
    orb-vo,fr1_xyz_first300,1,1305031102.175304,0.033188,11.212,0.6601,4.118,0.3120
    ...

One row per consecutive frame pair of one run (dataset x detector, back-end vo, every k-th frame):
ground-truth motion of the pair and the run's error on it, as pairs.py defines them.

The table is a function of (1) the engine's sources (slam-eval's trajectories), (2) the datasets,
(3) the study code that turns trajectories into rows. `make study` rewrites it
(`slam-study table --report build/study`); `slam-study table --check` (run by pytest) fails when it
is stale: rows edited by hand (rows_sha256), engine or study code changed since it was measured
(sha256 of their sources, recorded at generation), or its ground-truth motion columns disagree with
a recomputation from the TUM excerpts in tests/data (real data that is in the repository).
The sweep's datasets are outside the repository: their ground-truth files' sha256 are recorded.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import subprocess
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from slam_study import velocity
from slam_study.pairs import PairTable, motion_pairs
from slam_study.tum import Dataset, Trajectory, TumFormatError, is_rendered, read_trajectory

kRepoRoot = Path(__file__).resolve().parents[3]
kTablePath = Path(__file__).resolve().parent / "data" / "guide_pairs.csv"
kColumns = (
    "source",
    "dataset",
    "k",
    "stamp_s",
    "dt_s",
    "gt_trans_mm",
    "gt_rot_deg",
    "rpe_trans_mm",
    "rpe_rot_deg",
)
# The guide reads the plain front end only: frame-to-frame error is the front end's, and the
# vo/llc/glc runs of one detector would repeat the same frame pairs (report.kGridBackend).
kBackend = "vo"
# What slam-eval's trajectories depend on: the engine library, SURF, slam-eval's main. Tests and
# documents are left out (they do not change a trajectory); so are the top-level CMake files and
# compiler (a flag change is not caught: rerun `make study` after one).
kEngineSources = ("offboard/slam", "offboard/surf", "offboard/eval/app/slam_eval_main.cpp")
kEngineSuffixes = (".cpp", ".cc", ".h", ".hpp", ".txt")
kEngineExcludedDirs = ("tests",)
# The study code that turns trajectories into rows (the test recomputes the motion columns too).
kStudyCode = ("pairs.py", "se3.py", "tum.py", "velocity.py", "shipped.py")
# Ground-truth motion recomputed by the check agrees with the table to its printed digits.
kMotionTolMm = 2e-3
kMotionTolDeg = 2e-4
# Real TUM excerpts in the repository and the sweep dataset each is (part of): the check
# recomputes the table's ground-truth motion on their frames.
kRepoExcerpts = {
    "fr1_desk_9frames": "tests/data/fr1_desk_9frames",
    "fr1_xyz_first300": "tests/data/fr1_xyz_first30",
}


def _files_sha256(root: Path, entries, suffixes=None, excluded_dirs=()) -> str:
    """sha256 over (relative path, content) of every file under `entries` (files or folders),
    in path order; independent of mtimes and of git."""
    files = []
    for entry in entries:
        p = root / entry
        if p.is_file():
            files.append(p)
        elif p.is_dir():
            files += [
                f
                for f in p.rglob("*")
                if f.is_file()
                and (suffixes is None or f.suffix in suffixes or f.name == "CMakeLists.txt")
                and not any(part in excluded_dirs for part in f.relative_to(p).parts[:-1])
            ]
    h = hashlib.sha256()
    for f in sorted(files, key=lambda f: f.relative_to(root).as_posix()):
        h.update(f.relative_to(root).as_posix().encode() + b"\0")
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()


def engine_sources_sha256(root: Path = kRepoRoot) -> str:
    return _files_sha256(root, kEngineSources, kEngineSuffixes, kEngineExcludedDirs)


def study_code_sha256() -> str:
    here = Path(__file__).resolve().parent
    return _files_sha256(here, kStudyCode)


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass(frozen=True)
class ShippedTable:
    meta: dict[str, str]
    rows: list[dict[str, str]]
    datasets: dict[str, dict]  # name -> {"groundtruth_sha256": ..., "frames": ...}

    def sources(self) -> list[str]:
        return list(dict.fromkeys(r["source"] for r in self.rows))

    def default_source(self) -> str:
        """The source with the most pairs; ties by name."""
        counts: dict[str, int] = {}
        for r in self.rows:
            counts[r["source"]] = counts.get(r["source"], 0) + 1
        if not counts:
            raise TumFormatError("the guide table has no rows")
        return min(counts, key=lambda s: (-counts[s], s))

    def pairs(self, source: str) -> tuple[PairTable, np.ndarray, np.ndarray]:
        """(pairs, dataset name per pair, k per pair) of one source. Axis shares are not kept in
        the shipped table (the guide does not use them): they read as zero."""
        sel = [r for r in self.rows if r["source"] == source]
        if not sel:
            raise TumFormatError(
                f"the guide table has no source '{source}'; sources: {', '.join(self.sources())}"
            )
        col = {c: np.array([float(r[c]) for r in sel]) for c in kColumns[3:]}
        n = len(sel)
        pairs = PairTable(
            col["stamp_s"],
            col["dt_s"],
            col["gt_trans_mm"],
            col["gt_rot_deg"],
            np.zeros((n, 3)),
            np.zeros((n, 3)),
            col["rpe_trans_mm"],
            col["rpe_rot_deg"],
        )
        return (pairs, np.array([r["dataset"] for r in sel]), np.array([int(r["k"]) for r in sel]))

    def recorded_speed(self) -> tuple[float, float] | None:
        """(m/s, deg/s): the fastest 1 s of any recording the table rests on."""
        v = [d.get("max_trans_m_per_s") for d in self.datasets.values()]
        w = [d.get("max_rot_deg_per_s") for d in self.datasets.values()]
        if not v or None in v or None in w:
            return None
        return max(v), max(w)

    def describe(self) -> str:
        """One line of provenance for the guide's output."""
        ds = ", ".join(self.datasets)
        commit = self.meta.get("engine_commit", "?")
        short = commit[:12] + ("+uncommitted" if commit.endswith("+uncommitted") else "")
        return (
            f"measured {self.meta.get('generated_utc', '?')} with the engine at {short}\n"
            f"      on {ds} (TUM RGB-D excerpts),\n      every k-th frame, k = "
            f"{self.meta.get('k', '?')}"
        )


def _rows_text(rows: list[dict[str, str]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(kColumns)
    for r in rows:
        writer.writerow([r[c] for c in kColumns])
    return buf.getvalue()


def rows_sha256(rows: list[dict[str, str]]) -> str:
    return hashlib.sha256(_rows_text(rows).encode()).hexdigest()


def format_rows(source: str, dataset: str, k: int, p: PairTable) -> list[dict[str, str]]:
    return [
        {
            "source": source,
            "dataset": dataset,
            "k": str(k),
            "stamp_s": f"{p.stamp_s[i]:.6f}",
            "dt_s": f"{p.dt_s[i]:.6f}",
            "gt_trans_mm": f"{p.gt_trans_mm[i]:.3f}",
            "gt_rot_deg": f"{p.gt_rot_deg[i]:.4f}",
            "rpe_trans_mm": f"{p.rpe_trans_mm[i]:.3f}",
            "rpe_rot_deg": f"{p.rpe_rot_deg[i]:.4f}",
        }
        for i in range(len(p))
    ]


def _git_commit(root: Path) -> str:
    """HEAD, with "+uncommitted" when the engine's sources differ from it (informational: the
    sha256 of the sources is what the check compares)."""
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--", *kEngineSources],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        return head + ("+uncommitted" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def collect(
    report_dir: Path, warn
) -> tuple[list[dict[str, str]], dict[str, dict], set[str], list[int]]:
    """Rows from REPORT_DIR/runs/*/*-vo-k*/ (successful runs), the datasets they rest on, the
    engine-source hashes the runs recorded, and the k values."""
    rows, datasets, engine_hashes, ks = [], {}, set(), set()
    cache: dict[str, Dataset] = {}
    for result_path in sorted((Path(report_dir) / "runs").glob(f"*/*-{kBackend}-k*/result.json")):
        meta = json.loads(result_path.read_text())
        job = meta["job"]
        if meta.get("status") != "ok":
            warn(f"{result_path.parent}: failed run, not in the guide table ({meta.get('reason')})")
            continue
        ds_path = job["dataset"]
        name = Path(ds_path).name
        if is_rendered(ds_path):
            # The guide predicts a camera's error; rendered frames have no blur, no rolling shutter
            # and no lens distortion, so their error is a lower bound that would mislead it.
            raise TumFormatError(
                f"{result_path.parent}: {name} was rendered by hil/tools/render_tum.py; the "
                "guide's table rests on recorded sequences only (docs/study.md): read a rendered "
                "sweep with `slam-study guide --report REPORT_DIR` instead"
            )
        if name not in cache:
            cache[name] = Dataset.load(ds_path)
            stamps = cache[name].rgb_stamps_s
            v, w, _ = velocity.window_velocities(cache[name].groundtruth, stamps[0], stamps[-1])
            datasets[name] = {
                "groundtruth_sha256": file_sha256(Path(ds_path) / "groundtruth.txt"),
                "frames": int(stamps.size),
                # the recording's own speed (1 s windows, velocity.py): faster
                # motion is in the table only as frames dropped, without its blur
                "max_trans_m_per_s": round(float(v.max()), 3) if v.size else 0.0,
                "max_rot_deg_per_s": round(float(w.max()), 2) if w.size else 0.0,
            }
        est = read_trajectory(result_path.parent / "trajectory.tum")
        p = motion_pairs(cache[name].groundtruth, est)
        rows += format_rows(f"{job['features']}-{kBackend}", name, int(job["k"]), p)
        engine_hashes.add(job.get("engine_sources_sha256") or "not recorded")
        ks.add(int(job["k"]))
    rows.sort(key=lambda r: (r["source"], r["dataset"], int(r["k"]), r["stamp_s"]))
    return rows, dict(sorted(datasets.items())), engine_hashes, sorted(ks)


def write(
    report_dir: Path, out: Path, warn, root: Path = kRepoRoot, engine_commit: str | None = None
) -> ShippedTable:
    """Writes the table from a sweep's runs. Refuses runs whose recorded engine sources differ
    from the tree's (they were measured with another engine; `make study` redoes them).
    engine_commit: what to record as the engine's commit (default: git HEAD of root, marked
    "+uncommitted" when the engine's sources differ from it; for a tree exported with git
    archive)."""
    rows, datasets, engine_hashes, ks = collect(report_dir, warn)
    if not rows:
        raise TumFormatError(f"{report_dir}/runs holds no successful {kBackend} run: run the sweep")
    engine = engine_sources_sha256(root)
    if engine_hashes != {engine}:
        raise TumFormatError(
            f"{report_dir}/runs were made with engine sources {sorted(engine_hashes)}, the tree's "
            f"are {engine}: rerun the sweep (make study redoes runs of another engine)"
        )
    meta = {
        "generated_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "generated_by": "slam-study table --report <sweep> (make study); do not edit by hand",
        "engine_commit": engine_commit or _git_commit(root),
        "engine_sources_sha256": engine,
        "study_code_sha256": study_code_sha256(),
        "k": ",".join(map(str, ks)),
        "datasets": json.dumps(datasets, separators=(",", ":")),
        "rows_sha256": rows_sha256(rows),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    head = (
        "# slam-study guide table: per-frame-pair error of slam-eval's front end (back-end vo)"
        " on TUM RGB-D excerpts; docs/study.md\n"
    )
    text = head + "".join(f"# {k}: {v}\n" for k, v in meta.items()) + _rows_text(rows)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(text)
    tmp.replace(out)
    return ShippedTable(meta, rows, datasets)


def read(path: Path = kTablePath) -> ShippedTable:
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as err:
        raise TumFormatError(f"{path}: cannot read ({err.strerror})") from err
    meta = {}
    body = []
    for line in lines:
        if line.startswith("# ") and ": " in line and not body:
            key, value = line[2:].split(": ", 1)
            meta[key] = value
        elif not line.startswith("#"):
            body.append(line)
    reader = csv.DictReader(body)
    if tuple(reader.fieldnames or ()) != kColumns:
        raise TumFormatError(f"{path}: columns {reader.fieldnames}, expected {list(kColumns)}")
    rows = list(reader)
    try:
        datasets = json.loads(meta.get("datasets", "{}"))
    except ValueError as err:
        raise TumFormatError(f"{path}: malformed 'datasets' line ({err})") from err
    return ShippedTable(meta, rows, datasets)


def _recompute_motion(table: ShippedTable, name: str, ds: Dataset) -> tuple[int, list[str]]:
    """Recomputes gt_trans_mm / gt_rot_deg of the rows of dataset `name` whose two frames lie
    within ds's colour frames, from ds's ground truth. Returns (rows checked, problems)."""
    lo, hi = ds.rgb_stamps_s[0] - 1e-6, ds.rgb_stamps_s[-1] + 1e-6
    rows = [
        r
        for r in table.rows
        if r["dataset"] == name
        and lo <= float(r["stamp_s"])
        and float(r["stamp_s"]) + float(r["dt_s"]) <= hi
    ]
    problems = []
    for r in rows:
        a = float(r["stamp_s"])
        fake_est = Trajectory(np.array([a, a + float(r["dt_s"])]), np.stack([np.eye(4)] * 2))
        p = motion_pairs(ds.groundtruth, fake_est)
        if len(p) != 1:
            problems.append(f"{name} pair at {r['stamp_s']}: no ground truth in {ds.path}")
            continue
        if (
            abs(p.gt_trans_mm[0] - float(r["gt_trans_mm"])) > kMotionTolMm
            or abs(p.gt_rot_deg[0] - float(r["gt_rot_deg"])) > kMotionTolDeg
        ):
            problems.append(
                f"{name} {r['source']} k={r['k']} pair at {r['stamp_s']}: table "
                f"{r['gt_trans_mm']} mm / {r['gt_rot_deg']} deg, recomputed from "
                f"{ds.path.name} {p.gt_trans_mm[0]:.3f} / {p.gt_rot_deg[0]:.4f}"
            )
    return len(rows), problems


def engine_problem(table: ShippedTable, root: Path = kRepoRoot) -> str | None:
    """Why the table does not describe the engine in `root`, or None."""
    engine = engine_sources_sha256(root)
    if table.meta.get("engine_sources_sha256") == engine:
        return None
    return (
        "the engine's sources changed since the table was measured "
        f"({', '.join(kEngineSources)}: {table.meta.get('engine_sources_sha256')} -> {engine})"
    )


def check(
    table: ShippedTable,
    excerpts: dict[str, Path],
    root: Path = kRepoRoot,
    include_engine: bool = True,
) -> tuple[list[str], list[str]]:
    """(problems, checked): every way the table is found stale, and what was checked.
    `excerpts` maps a dataset name of the table to a TUM folder holding (part of) it; the rows in
    that folder's span get their ground-truth motion recomputed, and an identical ground-truth file
    is reported as such. include_engine=False leaves out the engine's sources (engine_problem)."""
    problems, checked = [], []
    if table.meta.get("rows_sha256") != rows_sha256(table.rows):
        problems.append("rows differ from rows_sha256 (edited by hand, or a bad merge)")
    checked.append(f"{len(table.rows)} rows against rows_sha256")
    if include_engine:
        found = engine_problem(table, root)
        problems += [found] if found else []
        checked.append(f"engine sources sha256 ({', '.join(kEngineSources)})")
    code = study_code_sha256()
    if table.meta.get("study_code_sha256") != code:
        problems.append(
            f"the study code that makes the rows changed ({', '.join(kStudyCode)}: "
            f"{table.meta.get('study_code_sha256')} -> {code})"
        )
    checked.append(f"study code sha256 ({', '.join(kStudyCode)})")
    for name, ds_dir in sorted(excerpts.items()):
        if name not in table.datasets:  # a table measured on other data (make study DATA=...)
            checked.append(f"{name}: not in the table, nothing to recompute from {ds_dir}")
            continue
        ds = Dataset.load(ds_dir)
        same = (
            file_sha256(Path(ds_dir) / "groundtruth.txt")
            == table.datasets[name]["groundtruth_sha256"]
        )
        n, found = _recompute_motion(table, name, ds)
        problems += found
        if n == 0:
            problems.append(f"no row of {name} lies within {ds_dir}'s frames")
        checked.append(
            f"{name}: ground-truth motion of {n} rows recomputed from {ds_dir} "
            f"({'same ground-truth file' if same else 'an excerpt'}; "
            f"{len(found)} disagree)"
        )
    return problems, checked


def regenerate_hint() -> str:
    return (
        "regenerate: `STUDY_BACKENDS=vo make study` (the vo runs only; needs ../shared/data "
        "or DATA=...: ~6 min of slam-eval CPU, 11 min wall on the shared 2 cores; a full "
        "`make study` regenerates it too), or `slam-study table --report build/study` when "
        "the sweep's runs are already there"
    )
