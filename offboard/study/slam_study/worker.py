"""One sweep run: invoke `slam-eval run` in a private temporary folder and return its outputs.

Standard library only, so the same function runs in a local thread or as a Ray task on another
machine (the package is shipped to the cluster with `py_modules`). The dataset path and the
slam-eval path must exist on the machine that runs it; the outputs travel back in the result, so
the report folder only has to exist on the driver.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from pathlib import Path

# Lines of slam-eval's stderr kept in a result: enough to show why a run failed.
kStderrTailLines = 30
# How often a running slam-eval is polled: negligible CPU, adds at most this to a run's wall time.
kPollS = 0.05


def job_command(slam_eval: str, job: dict, out_dir: str) -> list[str]:
    return [
        slam_eval,
        "run",
        "--dataset",
        job["dataset"],
        "--features",
        job["features"],
        "--backend",
        job["backend"],
        "--rate",
        str(job["k"]),
        "--mode",
        job["mode"],
        "--out",
        out_dir,
        *job.get("extra_args", []),
    ]


def execute_job(job: dict, slam_eval: str, timeout_s: float) -> dict:
    """Runs one job; never raises. Returns {status: ok|failed, returncode, reason, command,
    cpu_s (user+system CPU seconds of slam-eval, all threads; independent of other load on the
    machine), stderr_tail, trajectory (text or None), metrics (text or None)}.

    This is the process boundary, so it reads the clock, but only to enforce timeout_s."""
    with tempfile.TemporaryDirectory(prefix="slam-study-") as tmp:
        cmd = job_command(slam_eval, job, tmp)
        result = {
            "status": "failed",
            "returncode": None,
            "reason": "",
            "command": cmd,
            "cpu_s": None,
            "stderr_tail": "",
            "trajectory": None,
            "metrics": None,
        }
        err_path = Path(tmp) / "stderr.txt"
        try:
            with err_path.open("wb") as err_fh:
                proc = subprocess.Popen(
                    cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err_fh
                )
        except OSError as err:
            result["reason"] = f"cannot start {slam_eval}: {err.strerror}"
            return result
        status, usage, timed_out = _wait_with_usage(proc, timeout_s)
        result["cpu_s"] = round(usage.ru_utime + usage.ru_stime, 3)
        stderr = err_path.read_text("utf-8", "replace").splitlines()
        result["stderr_tail"] = "\n".join(stderr[-kStderrTailLines:])
        if timed_out:
            result["reason"] = f"timed out after {timeout_s:g} s"
            return result
        returncode = os.waitstatus_to_exitcode(status)
        result["returncode"] = returncode
        traj = Path(tmp) / "trajectory.tum"
        metrics = Path(tmp) / "metrics.json"
        if traj.is_file():
            result["trajectory"] = traj.read_text()
        if metrics.is_file():
            result["metrics"] = metrics.read_text()
        if returncode != 0:
            last = stderr[-1].strip() if stderr else ""
            result["reason"] = f"slam-eval exited with {returncode}" + (f": {last}" if last else "")
        elif result["trajectory"] is None:
            result["reason"] = "slam-eval wrote no trajectory.tum"
        else:
            result["status"] = "ok"
        return result


def _wait_with_usage(proc: subprocess.Popen, timeout_s: float):
    """Reaps proc with wait4 (for its own resource usage); kills it after timeout_s."""
    deadline = time.monotonic() + timeout_s
    timed_out = False
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if not timed_out and time.monotonic() > deadline:
            proc.kill()
            timed_out = True
        time.sleep(kPollS)
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
    return status, usage, timed_out
