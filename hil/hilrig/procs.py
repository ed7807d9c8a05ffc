"""Processes started by scenarios: started with Popen, logged to files, stopped by their own PID.

Never kills by name. `stop()` sends SIGTERM, waits `grace_s`, then SIGKILL, and always reaps.
Use as a context manager so a failing scenario still stops what it started.
"""

from __future__ import annotations

import subprocess
from pathlib import Path


class ManagedProcess:
    def __init__(
        self,
        argv: list[str],
        log_path: Path,
        cwd: Path | None = None,
        env=None,
        stdin_path: Path | None = None,
        stderr_path: Path | None = None,
    ) -> None:
        """stdout (and stderr unless stderr_path is given) go to log_path; stdin from stdin_path."""
        self.argv = [str(a) for a in argv]
        self.log_path = Path(log_path)
        self._log = open(self.log_path, "wb")
        self._err = open(stderr_path, "wb") if stderr_path else None
        self._stdin = open(stdin_path, "rb") if stdin_path else None
        self.proc = subprocess.Popen(
            self.argv,
            stdout=self._log,
            stderr=self._err if self._err else subprocess.STDOUT,
            stdin=self._stdin if self._stdin else subprocess.DEVNULL,
            cwd=cwd,
            env=env,
        )

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
        for f in (self._log, self._err, self._stdin):
            if f:
                f.close()
        return self.proc.returncode

    def log_text(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def __enter__(self) -> "ManagedProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
