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
                    "frame-rate questions from the measured grid.")
    sub = parser.add_subparsers(dest="command", required=True)

    def add_reference(p):
        p.add_argument("--reference", nargs=2, action="append", default=[],
                       metavar=("DATASET_DIR", "TRAJECTORY"),
                       help="also analyse an existing TUM trajectory (e.g. another system's) "
                            "against DATASET_DIR's ground truth, as its own source; repeatable")

    run = sub.add_parser("run", help="run the sweep (resumable), then write the report")
    run.add_argument("--data", nargs="+", required=True, metavar="DIR",
                     help="TUM-layout dataset folders, or folders whose sub-folders are datasets")
    run.add_argument("--out", required=True, type=Path, metavar="REPORT_DIR",
                     help="report folder; runs are kept in REPORT_DIR/runs and not redone")
    run.add_argument("--features", type=_csv_list(sweep.kFeatures),
                     default=list(sweep.kFeatures), help="comma list (default sift,surf,orb)")
    run.add_argument("--backends", type=_csv_list(sweep.kBackends),
                     default=list(sweep.kBackends), help="comma list (default vo,llc,glc)")
    run.add_argument("--k", type=_k_list, default=list(sweep.kDefaultKs),
                     help="frame-rate divisors: keep every k-th frame (default "
                          f"{','.join(map(str, sweep.kDefaultKs))})")
    run.add_argument("--mode", choices=("wait", "realtime"), default="wait",
                     help="slam-eval --mode (default wait: every kept frame is processed)")
    run.add_argument("--jobs", type=int, default=sweep.default_workers(),
                     help="parallel slam-eval processes on this machine (default: CPU count)")
    run.add_argument("--ray", metavar="ADDRESS",
                     help="run on an existing Ray cluster (e.g. 127.0.0.1:6379) instead of "
                          "locally; slam-eval and the data must be at the same paths on its nodes")
    run.add_argument("--slam-eval", default=_default_slam_eval(), metavar="PATH",
                     help="slam-eval binary (default $RGBD_BUILD_DIR/bin/slam-eval, "
                          "RGBD_BUILD_DIR defaulting to <repo>/build)")
    run.add_argument("--slam-eval-args", default="", metavar="ARGS",
                     help="extra options appended to every slam-eval run, one string "
                          "(e.g. \"--no-map --quiet\")")
    run.add_argument("--timeout-s", type=_positive, default=sweep.kDefaultRunTimeoutS,
                     help="per-run time limit in seconds (default %(default)g)")
    run.add_argument("--retry-failed", action="store_true",
                     help="redo runs that finished with a failure (successful runs are never redone)")
    run.add_argument("--no-report", action="store_true", help="only run the sweep")
    add_reference(run)

    rep = sub.add_parser("report", help="(re)write the report from REPORT_DIR/runs and references")
    rep.add_argument("--out", required=True, type=Path, metavar="REPORT_DIR")
    rep.add_argument("--k", type=_k_list, default=list(sweep.kDefaultKs),
                     help="rates listed in the Table 3.4 dataset tables (default %(default)s)")
    add_reference(rep)

    gd = sub.add_parser("guide", help="predict frame-to-frame error at candidate frame rates")
    gd.add_argument("--trans-vel", type=_non_negative, required=True, metavar="M_PER_S",
                    help="platform translational speed, m/s")
    gd.add_argument("--rot-vel", type=_non_negative, required=True, metavar="DEG_PER_S",
                    help="platform rotational speed, deg/s")
    gd.add_argument("--target-rpe-mm", type=_positive, metavar="X",
                    help="translational error per frame the platform can accept, mm: prints the "
                         "lowest candidate frame rate predicted to meet it")
    gd.add_argument("--report", type=Path, default=kRepoRoot / "build" / "study",
                    metavar="REPORT_DIR", help="report folder holding pairs.csv (default "
                                               "<repo>/build/study, where `make study` writes)")
    gd.add_argument("--source", help="which source's pairs to use, as named in pairs.csv (default: the one "
                         "with the most pairs)")
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
        return _guide(args)
    except (ValueError, OSError) as err:  # TumFormatError is a ValueError
        warn(f"error: {err}")
        return 2


def _run(args, warn) -> int:
    from slam_study import report, sweep, tum

    slam_eval = args.slam_eval
    if shutil.which(slam_eval) is None:
        warn(f"error: slam-eval not found or not executable at {slam_eval} "
             "(build it, or pass --slam-eval / set RGBD_BUILD_DIR)")
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
    jobs = sweep.make_jobs(datasets, args.features, args.backends, args.k, args.mode,
                           tuple(shlex.split(args.slam_eval_args)))
    todo = [j for j in jobs if not sweep.is_finished(j, args.out, args.retry_failed)]
    todo = sweep.longest_first(todo, {str(d.resolve()): tum.Dataset.load(d).rgb_stamps_s.size
                                      for d in datasets})
    warn(f"{len(jobs)} runs in the sweep, {len(jobs) - len(todo)} already finished, "
         f"{len(todo)} to do on {'Ray at ' + args.ray if args.ray else f'{args.jobs} local workers'}")
    clock = time.monotonic
    start = clock()
    progress = sweep.Progress(len(todo), sys.stderr, clock)
    if args.ray:
        failed = sweep.run_ray(todo, slam_eval, args.out, args.ray, args.timeout_s, progress)
    else:
        failed = sweep.run_local(todo, slam_eval, args.out, args.jobs, args.timeout_s, progress,
                                 clock)
    wall = clock() - start
    summary = sweep.summarize_runs(args.out)
    sweep.write_sweep_record(args.out, {**summary,
        "datasets": [str(d) for d in datasets], "features": args.features,
        "backends": args.backends, "k": args.k, "mode": args.mode,
        "slam_eval": slam_eval, "slam_eval_args": args.slam_eval_args,
        "executor": f"ray {args.ray}" if args.ray else f"local, {args.jobs} workers",
        "runs_total": len(jobs), "runs_this_invocation": len(todo),
        "failed_this_invocation": failed, "wall_s_this_invocation": round(wall, 1)})
    warn(f"sweep: {len(todo)} runs in {wall:.1f} s wall, {failed} failed; slam-eval CPU over all "
         f"{summary['runs_ok'] + summary['runs_failed']} recorded runs: "
         f"{summary['slam_eval_cpu_s_all_runs']:.0f} s")
    if not args.no_report:
        path = report.build(args.out, [tuple(r) for r in args.reference], args.k, warn)
        print(f"report: {path}")
    return 0


def _guide(args) -> int:
    from slam_study import guide, report

    pairs_csv = args.report / "pairs.csv"
    if not pairs_csv.is_file():
        print(f"slam-study: error: {pairs_csv} not found: run `slam-study run` or `slam-study "
              "report` first, or pass --report", file=sys.stderr)
        return 2
    pairs, source, _ = report.read_pairs_csv(pairs_csv, args.source)
    preds = guide.predict(pairs, args.trans_vel, args.rot_vel)
    sys.stdout.write(guide.guide_text(preds, args.trans_vel, args.rot_vel, args.target_rpe_mm,
                                      source))
    return 0
