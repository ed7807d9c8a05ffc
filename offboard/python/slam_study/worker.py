"""One sweep run: invoke `slam-eval run` in a private temporary folder and return its outputs.

Standard library only, so the same function runs in a local thread or as a Ray task on another
machine (the package is shipped to the cluster with `py_modules`). The dataset path and the
slam-eval path must exist on the machine that runs it; the outputs travel back in the result, so
the report folder only has to exist on the driver.
"""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

# Lines of slam-eval's stderr kept in a result: enough to show why a run failed.
kStderrTailLines = 30


def job_command(slam_eval: str, job: dict, out_dir: str) -> list[str]:
    return [slam_eval, "run", "--dataset", job["dataset"], "--features", job["features"],
            "--backend", job["backend"], "--rate", str(job["k"]), "--mode", job["mode"],
            "--out", out_dir, *job.get("extra_args", [])]


def execute_job(job: dict, slam_eval: str, timeout_s: float) -> dict:
    """Runs one job; never raises. Returns {status: ok|failed, returncode, reason, command,
    stderr_tail, trajectory (text or None), metrics (text or None)}."""
    with tempfile.TemporaryDirectory(prefix="slam-study-") as tmp:
        cmd = job_command(slam_eval, job, tmp)
        result = {"status": "failed", "returncode": None, "reason": "", "command": cmd,
                  "stderr_tail": "", "trajectory": None, "metrics": None}
        try:
            proc = subprocess.run(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.PIPE, timeout=timeout_s, check=False)
        except subprocess.TimeoutExpired:
            result["reason"] = f"timed out after {timeout_s:g} s"
            return result
        except OSError as err:
            result["reason"] = f"cannot start {slam_eval}: {err.strerror}"
            return result
        stderr = proc.stderr.decode("utf-8", "replace").splitlines()
        result["returncode"] = proc.returncode
        result["stderr_tail"] = "\n".join(stderr[-kStderrTailLines:])
        traj = Path(tmp) / "trajectory.tum"
        metrics = Path(tmp) / "metrics.json"
        if traj.is_file():
            result["trajectory"] = traj.read_text()
        if metrics.is_file():
            result["metrics"] = metrics.read_text()
        if proc.returncode != 0:
            result["reason"] = f"slam-eval exited with {proc.returncode}"
        elif result["trajectory"] is None:
            result["reason"] = "slam-eval wrote no trajectory.tum"
        else:
            result["status"] = "ok"
        return result
