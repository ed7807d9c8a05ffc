"""Command line of the study: `slam-study run | report | guide` (python -m slam_study).

Wiring only: argument parsing, the clock, stdout/stderr. The logic lives in sweep.py, report.py
and guide.py and takes time and streams as parameters.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import sys
import time
from pathlib import Path

kRepoRoot = Path(__file__).resolve().parents[3]


def _default_slam_eval() -> str:
    build = Path(os.environ.get("RGBD_BUILD_DIR", kRepoRoot / "build"))
    return str(build / "bin" / "slam-eval")


def _csv_list(allowed: tuple[str, ...] | None):
    def parse(text: str) -> list[str]:
        items = [t.strip() for t in text.split(",") if t.strip()]
        if not items:
            raise argparse.ArgumentTypeError("empty list")
        if allowed is not None:
            bad = [t for t in items if t not in allowed]
            if bad:
                raise argparse.ArgumentTypeError(f"unknown {bad}; choose from {','.join(allowed)}")
        return items

    return parse


def _k_list(text: str) -> list[int]:
    try:
        ks = sorted({int(t) for t in text.split(",") if t.strip()})
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"k values must be integers: {err}") from err
    if not ks or ks[0] < 1:
        raise argparse.ArgumentTypeError("k values must be integers >= 1")
    return ks


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from err
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError("must be a finite number > 0")
    return v


def _non_negative(text: str) -> float:
    try:
        v = float(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from err
    if not (v >= 0 and v < float("inf")):
        raise argparse.ArgumentTypeError("must be a finite number >= 0")
    return v


def build_parser() -> argparse.ArgumentParser:
    from slam_study import sweep

    parser = argparse.ArgumentParser(
        prog="slam-study",
        description="Spatial-velocity study (thesis Chapter 4): sweep slam-eval over TUM RGB-D "
        "datasets x detector x back-end x frame-rate divisor k, bin the per-pair error "
        "by ground-truth motion, write a Markdown/CSV/PNG report, and answer "
        "frame-rate questions from the measured grid.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    def add_reference(p):
        p.add_argument(
            "--reference",
            nargs=2,
            action="append",
            default=[],
            metavar=("DATASET_DIR", "TRAJECTORY"),
            help="also analyse an existing TUM trajectory (e.g. another system's) "
            "against DATASET_DIR's ground truth, as its own source; repeatable",
        )

    run = sub.add_parser("run", help="run the sweep (resumable), then write the report")
    run.add_argument(
        "--data",
        nargs="+",
        required=True,
        metavar="DIR",
        help="TUM-layout dataset folders, or folders whose sub-folders are datasets; folders "
        "rendered by hil/tools/render_tum.py are swept on their own, with --slam-eval-args "
        '"... --no-undistort"',
    )
    run.add_argument(
        "--out",
        required=True,
        type=Path,
        metavar="REPORT_DIR",
        help="report folder; runs are kept in REPORT_DIR/runs and not redone",
    )
    run.add_argument(
        "--features",
        type=_csv_list(sweep.kFeatures),
        default=list(sweep.kFeatures),
        help="comma list (default sift,surf,orb)",
    )
    run.add_argument(
        "--backends",
        type=_csv_list(sweep.kBackends),
        default=list(sweep.kBackends),
        help="comma list (default vo,llc,glc)",
    )
    run.add_argument(
        "--k",
        type=_k_list,
        default=list(sweep.kDefaultKs),
        help="frame-rate divisors: keep every k-th frame (default "
        f"{','.join(map(str, sweep.kDefaultKs))})",
    )
    run.add_argument(
        "--mode",
        choices=("wait", "realtime"),
        default="wait",
        help="slam-eval --mode (default wait: every kept frame is processed)",
    )
    run.add_argument(
        "--jobs",
        type=int,
        default=sweep.default_workers(),
        help="parallel slam-eval processes on this machine (default: CPU count)",
    )
    run.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on an existing Ray cluster (e.g. 127.0.0.1:6379) instead of "
        "locally; slam-eval and the data must be at the same paths on its nodes",
    )
    run.add_argument(
        "--slam-eval",
        default=_default_slam_eval(),
        metavar="PATH",
        help="slam-eval binary (default $RGBD_BUILD_DIR/bin/slam-eval, "
        "RGBD_BUILD_DIR defaulting to <repo>/build)",
    )
    run.add_argument(
        "--slam-eval-args",
        default="",
        metavar="ARGS",
        help='extra options appended to every slam-eval run, one string (e.g. "--no-map --quiet")',
    )
    run.add_argument(
        "--timeout-s",
        type=_positive,
        default=sweep.kDefaultRunTimeoutS,
        help="per-run time limit in seconds (default %(default)g)",
    )
    run.add_argument(
        "--retry-failed",
        action="store_true",
        help="redo runs that finished with a failure (successful runs are never redone)",
    )
    run.add_argument("--no-report", action="store_true", help="only run the sweep")
    add_reference(run)

    rep = sub.add_parser("report", help="(re)write the report from REPORT_DIR/runs and references")
    rep.add_argument("--out", required=True, type=Path, metavar="REPORT_DIR")
    rep.add_argument(
        "--k",
        type=_k_list,
        default=list(sweep.kDefaultKs),
        help="rates listed in the Table 3.4 dataset tables (default %(default)s)",
    )
    add_reference(rep)

    gd = sub.add_parser(
        "guide",
        help="predict frame-to-frame error at candidate frame rates",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="For a platform moving at --trans-vel and --rot-vel, the per-frame motion at "
        "30/k fps (k = 1..8) and the error measured for that motion: a cell of the "
        "study's grid, its pairs per sequence, mean with a 95 %% confidence interval "
        "and 90th percentile. Motion beyond what was measured, or a cell with < 5 "
        "pairs, gets no prediction. Reads the table shipped in the repository "
        "(offboard/study/slam_study/data/guide_pairs.csv, made by `make study`) "
        "unless --report names a sweep's report folder.",
        epilog="examples:\n"
        "  slam-study guide --trans-vel 0.41 --rot-vel 23 --target-rpe-mm 8\n"
        "      thesis-typical hand-held motion (fr1/desk: 0.41 m/s, 23 deg/s): per rate the\n"
        "      cell, n per sequence, mean [95 % CI], p90, and the lowest rate whose CI\n"
        "      stays within 8 mm per frame\n"
        "  slam-study guide --trans-vel 0.1 --rot-vel 3 --source sift-vo\n"
        "  slam-study guide --trans-vel 0.3 --rot-vel 15 --report build/study\n"
        "      from your own sweep (slam-study run ... --out build/study)",
    )
    gd.add_argument(
        "--trans-vel",
        type=_non_negative,
        required=True,
        metavar="M_PER_S",
        help="platform translational speed, m/s",
    )
    gd.add_argument(
        "--rot-vel",
        type=_non_negative,
        required=True,
        metavar="DEG_PER_S",
        help="platform rotational speed, deg/s",
    )
    gd.add_argument(
        "--target-rpe-mm",
        type=_positive,
        metavar="X",
        help="translational error per frame the platform can accept, mm: prints the "
        "lowest candidate frame rate whose 95 %% interval stays within it",
    )
    gd.add_argument(
        "--report",
        type=Path,
        metavar="REPORT_DIR",
        help="use REPORT_DIR/pairs.csv from a sweep instead of the shipped table",
    )
    gd.add_argument(
        "--table",
        type=Path,
        default=None,
        metavar="CSV",
        help="shipped-table file (default offboard/study/slam_study/data/guide_pairs.csv)",
    )
    gd.add_argument(
        "--source",
        help="which source's pairs to use (default: the one with the most "
        "pairs; shipped: sift-vo, surf-vo, orb-vo)",
    )

    tb = sub.add_parser("table", help="write the guide's shipped table from a sweep, or --check it")
    tb.add_argument(
        "--report",
        type=Path,
        metavar="REPORT_DIR",
        help="sweep folder (REPORT_DIR/runs) to build the table from",
    )
    tb.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="CSV",
        help="table file (default: the shipped one)",
    )
    tb.add_argument(
        "--engine-commit",
        metavar="SHA",
        help="commit to record for the engine (default: git HEAD, '+uncommitted' when "
        "the engine's sources differ from it); for a tree exported by git archive",
    )
    tb.add_argument(
        "--check",
        action="store_true",
        help="exit 1 if the table is stale: rows edited, engine or study code changed "
        "since it was measured, or its ground-truth motion disagrees with the TUM "
        "excerpts in tests/data",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)

    def warn(msg: str) -> None:
        print(f"slam-study: {msg}", file=sys.stderr)

    try:
        if args.command == "run":
            return _run(args, warn)
        if args.command == "report":
            from slam_study import report

            path = report.build(args.out, [tuple(r) for r in args.reference], args.k, warn)
            print(f"report: {path}")
            return 0
        if args.command == "table":
            return _table(args, warn)
        return _guide(args)
    except (ValueError, OSError) as err:  # TumFormatError is a ValueError
        warn(f"error: {err}")
        return 2


def _engine_sha256(slam_eval: str) -> str:
    """The engine sources' sha256 when slam-eval is built in this repository (recorded per run, so
    a changed engine is re-measured); "" (not tracked) for a binary from elsewhere."""
    from slam_study import shipped

    resolved = Path(shutil.which(slam_eval) or slam_eval).resolve()
    return shipped.engine_sources_sha256() if resolved.is_relative_to(kRepoRoot) else ""


def _run(args, warn) -> int:
    from slam_study import report, sweep, tum

    slam_eval = args.slam_eval
    if shutil.which(slam_eval) is None:
        warn(
            f"error: slam-eval not found or not executable at {slam_eval} "
            "(build it, or pass --slam-eval / set RGBD_BUILD_DIR)"
        )
        return 2
    if args.jobs < 1:
        warn("error: --jobs must be >= 1")
        return 2
    datasets = tum.find_datasets(args.data)
    if not datasets:
        warn(f"error: no TUM-layout dataset (rgb.txt + groundtruth.txt) under {args.data}")
        return 2
    for d in datasets:
        tum.Dataset.load(d)  # fail early, with the file and line, on a malformed dataset
    extra_args = tuple(shlex.split(args.slam_eval_args))
    problem = sweep.undistort_problem(datasets, extra_args)
    if problem:
        warn(f"error: {problem}")
        return 2
    jobs = sweep.make_jobs(
        datasets,
        args.features,
        args.backends,
        args.k,
        args.mode,
        extra_args,
        _engine_sha256(slam_eval),
    )
    todo = [j for j in jobs if not sweep.is_finished(j, args.out, args.retry_failed)]
    todo = sweep.longest_first(
        todo, {str(d.resolve()): tum.Dataset.load(d).rgb_stamps_s.size for d in datasets}
    )
    warn(
        f"{len(jobs)} runs in the sweep, {len(jobs) - len(todo)} already finished, "
        f"{len(todo)} to do on {'Ray at ' + args.ray if args.ray else f'{args.jobs} local workers'}"
    )
    clock = time.monotonic
    start = clock()
    progress = sweep.Progress(len(todo), sys.stderr, clock)
    if args.ray:
        failed = sweep.run_ray(todo, slam_eval, args.out, args.ray, args.timeout_s, progress)
    else:
        failed = sweep.run_local(
            todo, slam_eval, args.out, args.jobs, args.timeout_s, progress, clock
        )
    wall = clock() - start
    summary = sweep.summarize_runs(args.out)
    sweep.write_sweep_record(
        args.out,
        {
            **summary,
            "datasets": [str(d) for d in datasets],
            "features": args.features,
            "backends": args.backends,
            "k": args.k,
            "mode": args.mode,
            "slam_eval": slam_eval,
            "slam_eval_args": args.slam_eval_args,
            "executor": f"ray {args.ray}" if args.ray else f"local, {args.jobs} workers",
            "runs_total": len(jobs),
            "runs_this_invocation": len(todo),
            "failed_this_invocation": failed,
            "wall_s_this_invocation": round(wall, 1),
        },
    )
    warn(
        f"sweep: {len(todo)} runs in {wall:.1f} s wall, {failed} failed; slam-eval CPU over all "
        f"{summary['runs_ok'] + summary['runs_failed']} recorded runs: "
        f"{summary['slam_eval_cpu_s_all_runs']:.0f} s"
    )
    if not args.no_report:
        path = report.build(args.out, [tuple(r) for r in args.reference], args.k, warn)
        print(f"report: {path}")
    return 0


def _guide(args) -> int:
    from slam_study import guide, report, shipped

    if args.report is not None:
        pairs_csv = args.report / "pairs.csv"
        if not pairs_csv.is_file():
            print(
                f"slam-study: error: {pairs_csv} not found: run `slam-study run` or "
                "`slam-study report` first, or leave out --report for the shipped table",
                file=sys.stderr,
            )
            return 2
        pairs, source, _ = report.read_pairs_csv(pairs_csv, args.source)
        datasets = report.read_pairs_datasets(pairs_csv, source)
        provenance = f"sweep {args.report}"
        recorded_speed = None
    else:
        path = args.table or shipped.kTablePath
        table = shipped.read(path)
        source = args.source or table.default_source()
        pairs, datasets, _ = table.pairs(source)
        try:
            shown = path.resolve().relative_to(kRepoRoot)
        except ValueError:
            shown = path
        provenance = f"table {shown},\n      {table.describe()}"
        drift = shipped.engine_problem(table)
        if drift:
            # Engine changes land more often than the 11-minute re-measurement: say so, do not hide
            # it.
            provenance += (
                f"\n      NOTE: {drift}; the errors may have moved since "
                f"({shipped.regenerate_hint()})"
            )
        recorded_speed = table.recorded_speed()
        source = f"slam-eval {source}"
    preds = guide.predict(pairs, args.trans_vel, args.rot_vel, datasets=datasets)
    sys.stdout.write(
        guide.guide_text(
            preds,
            args.trans_vel,
            args.rot_vel,
            args.target_rpe_mm,
            source,
            pairs,
            provenance,
            recorded_speed,
        )
    )
    return 0


def _table(args, warn) -> int:
    from slam_study import shipped

    out = args.out or shipped.kTablePath
    if args.check:
        excerpts = {name: kRepoRoot / rel for name, rel in shipped.kRepoExcerpts.items()}
        problems, checked = shipped.check(shipped.read(out), excerpts)
        for line in checked:
            print(f"checked: {line}")
        if problems:
            for line in problems:
                warn(f"stale: {line}")
            warn(f"{out} is stale: {shipped.regenerate_hint()}")
            return 1
        print(f"{out}: up to date")
        return 0
    if args.report is None:
        warn("error: --report REPORT_DIR (a sweep folder) or --check is needed")
        return 2
    table = shipped.write(args.report, out, warn, engine_commit=args.engine_commit)
    print(
        f"guide table: {out} ({len(table.rows)} pairs, sources {', '.join(table.sources())}, "
        f"datasets {', '.join(table.datasets)})"
    )
    return 0
