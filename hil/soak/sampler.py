"""Samples the memory (VmRSS of /proc/PID/status) and open descriptors (/proc/PID/fd) of every
process of the soak, on its own thread, every `period_s`. A process is keyed by name and PID, so a
restarted process (quad-control each mission, slam-server after a kill) starts a new series.
"""

from __future__ import annotations

import os
import threading
import time


def rss_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def fd_count(pid: int) -> int | None:
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None


class ResourceSampler:
    def __init__(self, pids, period_s: float, samples: dict, t0: float) -> None:
        """pids() -> {name: pid}; samples: "name pid" -> [(elapsed_s, rss_kb, fds)], filled in."""
        self._pids = pids
        self.period_s = period_s
        self.samples = samples
        self.t0 = t0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="soak-sampler", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10)
        self.sample()

    def sample(self) -> None:
        try:
            pids = self._pids()
        except Exception:  # noqa: BLE001 - a flight being torn down: no sample this time
            return
        now = round(time.monotonic() - self.t0, 1)
        for name, pid in pids.items():
            rss, fds = rss_kb(pid), fd_count(pid)
            if rss is None:
                continue
            self.samples.setdefault(f"{name} {pid}", []).append((now, rss, fds))

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            self.sample()
