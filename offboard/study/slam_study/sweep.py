"""The sweep: datasets x detector x back-end x frame-rate divisor k, each one `slam-eval run`.

Runs in parallel on local cores (threads, each waiting on one slam-eval process) or on an existing
Ray cluster. Resumable: a run whose `result.json` exists is not redone (failed runs too, unless
retry_failed) - unless it was made with other engine sources than the job's (each job carries the
sha256 of the engine's sources, shipped.engine_sources_sha256, and its result.json records it).
Layout under the report folder:
    runs/<dataset>/<features>-<backend>-k<k>/{trajectory.tum, metrics.json, result.json, stderr.txt}
Time is passed in (`clock_s`), for the progress line and the recorded wall time only.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TextIO

from slam_study import tum
from slam_study.worker import execute_job

kFeatures = ("sift", "surf", "orb")
kBackends = ("vo", "llc", "glc")
# Default k set: 30, 15, 10, 7.5, 6, 3.75 fps (k = 6, 7 left out to keep the whole sweep on the
# shared data inside the < 15 min budget on 2 cores, docs/study.md; add them with --k).
kDefaultKs = (1, 2, 3, 4, 5, 8)
# A single run on the shared data takes seconds; this only catches a hung process.
kDefaultRunTimeoutS = 900.0


# slam-eval's switch for frames without lens distortion (rendered ones); recordings of the Kinect
# are undistorted with the sequence's calibration, so they must run without it.
kNoUndistortArg = "--no-undistort"


def undistort_problem(datasets: list[Path], extra_args: tuple[str, ...]) -> str | None:
    """Why these datasets cannot be swept with these slam-eval options, or None.

    Folders rendered by hil/tools/render_tum.py need --no-undistort, recordings must not have it,
    and one sweep passes the same options to every run: so rendered folders are swept on their own
    (into their own report folder, which also keeps synthetic pairs out of the recordings' grid
    and out of the guide's shipped table, docs/study.md)."""
    rendered = [d for d in datasets if tum.is_rendered(d)]
    recorded = [d for d in datasets if d not in rendered]
    no_undistort = kNoUndistortArg in extra_args

    def names(ds: list[Path]) -> str:
        return ", ".join(d.name for d in ds)

    if rendered and recorded:
        return (
            f"{names(rendered)} rendered by hil/tools/render_tum.py and {names(recorded)} "
            "recorded by a camera in one sweep: sweep them apart (rendered frames run with "
            f"{kNoUndistortArg}, recorded ones are undistorted; their pairs are reported apart)"
        )
    if rendered and not no_undistort:
        return (
            f"{names(rendered)} rendered by hil/tools/render_tum.py: the frames have no lens "
            f'distortion, add {kNoUndistortArg} to --slam-eval-args (e.g. "--no-map --quiet '
            f'{kNoUndistortArg}")'
        )
    if recorded and no_undistort:
        return (
            f"{kNoUndistortArg} with {names(recorded)}: recorded frames carry the camera's lens "
            "distortion and must be undistorted (the option is for rendered folders only)"
        )
    return None


@dataclass(frozen=True)
class Job:
    dataset: str  # absolute path of the TUM-layout folder
    features: str
    backend: str
    k: int
    mode: str = "wait"
    extra_args: tuple[str, ...] = ()  # passed to slam-eval after the standard options
    engine_sources_sha256: str = ""  # of the tree slam-eval was built from ("" = not tracked)

    @property
    def name(self) -> str:
        return f"{Path(self.dataset).name}/{self.features}-{self.backend}-k{self.k}"

    def run_dir(self, out: Path) -> Path:
        return out / "runs" / Path(self.dataset).name / f"{self.features}-{self.backend}-k{self.k}"


def make_jobs(
    datasets: list[Path],
    features: list[str],
    backends: list[str],
    ks: list[int],
    mode: str = "wait",
    extra_args: tuple[str, ...] = (),
    engine_sources_sha256: str = "",
) -> list[Job]:
    names = [d.name for d in datasets]
    if len(set(names)) != len(names):
        raise ValueError(
            f"dataset folder names must be unique (they name the run folders): {names}"
        )
    return [
        Job(str(d.resolve()), f, b, k, mode, tuple(extra_args), engine_sources_sha256)
        for d in datasets
        for f in features
        for b in backends
        for k in ks
    ]


# Relative per-frame cost of the detectors, for ordering only (slam-eval on fr1_desk, 9 frames:
# sift ~4x orb; surf assumed like sift).
kFeatureCostWeight = {"sift": 4.0, "surf": 4.0, "orb": 1.0}


def longest_first(jobs: list[Job], frames_by_dataset: dict[str, int]) -> list[Job]:
    """Expected-longest runs first (frames kept x detector weight), so the last runs to finish are
    short ones and the workers stay busy to the end (LPT scheduling)."""

    def cost(job: Job) -> float:
        frames = frames_by_dataset.get(job.dataset, 0) / job.k
        return frames * kFeatureCostWeight.get(job.features, 1.0)

    return sorted(jobs, key=cost, reverse=True)


def is_finished(job: Job, out: Path, retry_failed: bool) -> bool:
    result = job.run_dir(out) / "result.json"
    if not result.is_file():
        return False
    try:
        meta = json.loads(result.read_text())
    except (OSError, ValueError):
        return False
    recorded_engine = meta.get("job", {}).get("engine_sources_sha256", "")
    if job.engine_sources_sha256 and recorded_engine != job.engine_sources_sha256:
        return False  # measured with other engine sources: stale
    status = meta.get("status")
    return status == "ok" or (status == "failed" and not retry_failed)


def store_result(job: Job, out: Path, result: dict, wall_s: float | None) -> None:
    """Writes a run's outputs; result.json last, so a crash mid-write leaves the run unfinished."""
    run_dir = job.run_dir(out)
    run_dir.mkdir(parents=True, exist_ok=True)
    for key, fname in (("trajectory", "trajectory.tum"), ("metrics", "metrics.json")):
        if result.get(key) is not None:
            (run_dir / fname).write_text(result[key])
    (run_dir / "stderr.txt").write_text(result.get("stderr_tail", ""))
    meta = {k: v for k, v in result.items() if k not in ("trajectory", "metrics", "stderr_tail")}
    meta["job"] = asdict(job)
    meta["wall_s"] = wall_s
    tmp = run_dir / "result.json.tmp"
    tmp.write_text(json.dumps(meta, indent=1))
    tmp.replace(run_dir / "result.json")


class Progress:
    """A one-line progress bar on a stream (redrawn in place on a terminal, a line per run else)."""

    def __init__(self, total: int, stream: TextIO, clock_s: Callable[[], float], width: int = 30):
        self.total, self.stream, self.clock_s, self.width = total, stream, clock_s, width
        self.done = self.failed = 0
        self.start_s = clock_s()
        self.tty = hasattr(stream, "isatty") and stream.isatty()

    def update(self, name: str, ok: bool) -> None:
        self.done += 1
        self.failed += 0 if ok else 1
        filled = self.width * self.done // max(self.total, 1)
        elapsed = self.clock_s() - self.start_s
        line = (
            f"[{'#' * filled}{'.' * (self.width - filled)}] {self.done}/{self.total} runs"
            f" ({self.failed} failed) {elapsed:6.1f} s  {name}{'' if ok else ' FAILED'}"
        )
        if self.tty:
            self.stream.write("\r" + line[:150].ljust(150))
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


def run_local(
    jobs: list[Job],
    slam_eval: str,
    out: Path,
    workers: int,
    timeout_s: float,
    progress: Progress,
    clock_s: Callable[[], float],
) -> int:
    """Runs jobs on `workers` local slam-eval processes at a time. Returns the failed count."""
    failed = 0
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:

        def timed(job: Job):
            start = clock_s()
            return execute_job(asdict(job), slam_eval, timeout_s), clock_s() - start

        futures = {pool.submit(timed, job): job for job in jobs}
        for fut in as_completed(futures):
            job = futures[fut]
            result, wall_s = fut.result()
            store_result(job, out, result, wall_s)
            ok = result["status"] == "ok"
            failed += 0 if ok else 1
            progress.update(job.name, ok)
    return failed


def run_ray(
    jobs: list[Job], slam_eval: str, out: Path, address: str, timeout_s: float, progress: Progress
) -> int:
    """Runs jobs as Ray tasks (1 CPU each) on the cluster at `address` (e.g. 127.0.0.1:6379).

    The slam_study package is shipped with the job (runtime_env py_modules); slam-eval and the
    datasets must be at the same paths on every node. Returns the failed count."""
    import ray  # imported here: local sweeps do not need Ray installed

    package_dir = str(Path(__file__).resolve().parent)
    ray.init(
        address=address,
        runtime_env={"py_modules": [package_dir]},
        log_to_driver=False,
        logging_level="ERROR",
    )
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_ray_task)
        pending = {remote.remote(asdict(job), slam_eval, timeout_s): job for job in jobs}
        failed = 0
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                job = pending.pop(ref)
                try:
                    result, wall_s = ray.get(ref)
                except Exception as err:  # noqa: BLE001
                    # a task that died on its node: record, go on
                    result, wall_s = (
                        {
                            "status": "failed",
                            "reason": f"ray task failed: {err}",
                            "returncode": None,
                            "command": [],
                        },
                        None,
                    )
                store_result(job, out, result, wall_s)
                ok = result["status"] == "ok"
                failed += 0 if ok else 1
                progress.update(job.name, ok)
        return failed
    finally:
        ray.shutdown()


def _ray_task(job: dict, slam_eval: str, timeout_s: float):
    import time  # a worker-side wall time for the record; the logic does not depend on it

    start = time.monotonic()
    result = execute_job(job, slam_eval, timeout_s)
    return result, time.monotonic() - start


def default_workers() -> int:
    return os.cpu_count() or 1


def summarize_runs(out: Path) -> dict:
    """Counts and CPU seconds over every run recorded under out/runs (all invocations)."""
    ok = failed = 0
    cpu_s = 0.0
    for path in (out / "runs").glob("*/*/result.json"):
        try:
            meta = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        ok += meta.get("status") == "ok"
        failed += meta.get("status") != "ok"
        cpu_s += meta.get("cpu_s") or 0.0
    return {"runs_ok": ok, "runs_failed": failed, "slam_eval_cpu_s_all_runs": round(cpu_s, 1)}


def write_sweep_record(out: Path, record: dict) -> None:
    """Appends this invocation's record to out/sweep.json ({"invocations": [...]}), so resuming a
    sweep keeps the wall time of the invocations that did the work."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "sweep.json"
    history: list = []
    try:
        history = json.loads(path.read_text()).get("invocations", [])
    except (OSError, ValueError, AttributeError):
        history = []
    history.append(record)
    path.write_text(json.dumps({"invocations": history}, indent=1))
