"""One real-time HIL flight per machine.

A closed-loop flight runs the rig (simavr + FC emulator + Kinect renderer) at SCHED_RR 11 and the
ground station's SLAM/control threads at 10-12 (hilrig.realtime). Two flights on one 2-core machine
starve each other's SLAM - measured twice: tracking lost, link timeouts - and both
report failures that belong to neither system. So a flight takes this machine-wide lock before it
raises any priority, and a second flight waits for the first to end (printing who holds it) instead
of corrupting both measurements.

The lock is an flock(2) on a file in /tmp (HIL_FLIGHT_LOCK overrides the path): released by the
kernel when the holder exits, however it exits, so a crashed flight never leaves a stale lock.
"""

from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path
from typing import Callable

DEFAULT_LOCK_PATH = Path("/tmp/rgbdquad-hil-flight.lock")
# A full `make hil` is ~25 min and the 10-minute long flight ~12 min; waiting 40 min covers one of
# either ahead of us, and a wait beyond that is more likely a hung flight that needs a person.
DEFAULT_WAIT_S = 2400.0
# How often a waiting flight says it is still waiting (a silent wait looks like a hang).
PROGRESS_PERIOD_S = 30.0
POLL_PERIOD_S = 0.5


class FlightLockTimeout(RuntimeError):
    pass


def lock_path() -> Path:
    return Path(os.environ.get("HIL_FLIGHT_LOCK", str(DEFAULT_LOCK_PATH)))


def wait_s() -> float:
    return float(os.environ.get("HIL_FLIGHT_LOCK_WAIT_S", str(DEFAULT_WAIT_S)))


class FlightLock:
    """Machine-wide exclusive lock for one HIL flight. `acquire` blocks (polling, with progress
    lines through `say`) up to `wait_s`; `release` is idempotent."""

    def __init__(
        self,
        path: Path | None = None,
        wait_s_: float | None = None,
        say: Callable[[str], None] = print,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.path = Path(path) if path is not None else lock_path()
        self.wait_s = wait_s() if wait_s_ is None else wait_s_
        self._say = say
        self._clock = clock
        self._sleep = sleep
        self._fd: int | None = None
        self.waited_s = 0.0

    def holder(self) -> str:
        try:
            text = self.path.read_text().strip()
        except OSError:
            return "unknown"
        return text or "unknown"

    def acquire(self, what: str) -> "FlightLock":
        if self._fd is not None:
            return self
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        start = self._clock()
        next_say = start
        try:
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError as busy:
                    now = self._clock()
                    if now - start >= self.wait_s:
                        raise FlightLockTimeout(
                            f"another HIL flight holds {self.path} ({self.holder()}) for more than "
                            f"{self.wait_s:.0f} s; two real-time flights on one machine "
                            "starve each other, so this one does not start "
                            "(HIL_FLIGHT_LOCK_WAIT_S to wait longer)"
                        ) from busy
                    if now >= next_say:
                        self._say(
                            f"hil: waiting for another HIL flight to end ({self.holder()}), "
                            f"{now - start:.0f} s so far"
                        )
                        next_say = now + PROGRESS_PERIOD_S
                    self._sleep(POLL_PERIOD_S)
        except BaseException:
            os.close(fd)
            raise
        self.waited_s = self._clock() - start
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}: {what}\n".encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            os.ftruncate(fd, 0)
        finally:
            os.close(fd)  # closing the only descriptor releases the flock
