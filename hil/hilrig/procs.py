"""Processes started by scenarios: started with Popen, logged to files, stopped by their own PID.

Never kills by name. `stop()` sends SIGTERM, waits `grace_s`, then SIGKILL, and always reaps.
Use as a context manager so a failing scenario still stops what it started.
"""

from __future__ import annotations

from pathlib import Path
import subprocess


class ManagedProcess:
    def __init__(self, argv: list[str], log_path: Path, cwd: Path | None = None, env=None) -> None:
        self.argv = [str(a) for a in argv]
        self.log_path = Path(log_path)
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(self.argv, stdout=self._log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, cwd=cwd, env=env)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def wait(self, timeout_s: float) -> int:
        return self.proc.wait(timeout=timeout_s)

    def stop(self, grace_s: float = 3.0) -> int:
        if self.proc.poll() is None:
            self.proc.terminate()  # signals this PID only
            try:
                self.proc.wait(timeout=grace_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=grace_s)
        self._log.close()
        return self.proc.returncode

    def log_text(self) -> str:
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def __enter__(self) -> "ManagedProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
