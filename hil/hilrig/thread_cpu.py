"""CPU time per thread of a running process, from /proc/PID/task/*/stat.

The ground station's threads are named (pthread_setname_np: qc-frame, qc-slam-link, qc-firmware,
qc-dashboard, qc-recorder, rx-rgb, rx-depth, slam-tracking, slam-mapping, slam-loop, ...), so a
flight can say where its CPU went instead of a process total. Threads of the same name (a pool,
or a thread restarted) are summed. Instrumentation only: a process or thread that exits while it
is read is skipped.
"""

from __future__ import annotations

import os
from pathlib import Path

CLOCK_TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def parse_stat(text: str) -> tuple[str, float]:
    """(comm, utime + stime in seconds) from one /proc/.../stat line. comm sits in parentheses and
    may itself hold spaces or parentheses, so the fields are counted after its last ')'."""
    open_paren, close_paren = text.index("("), text.rindex(")")
    comm = text[open_paren + 1 : close_paren]
    fields = text[close_paren + 2 :].split()
    # Fields after comm start at field 3 (state); utime and stime are fields 14 and 15.
    utime, stime = int(fields[11]), int(fields[12])
    return comm, (utime + stime) / CLOCK_TICKS_PER_S


def process_cpu_s(pid: int, proc_root: Path = Path("/proc")) -> float:
    """CPU seconds used so far by process `pid`, all its threads together."""
    return parse_stat((proc_root / str(pid) / "stat").read_text())[1]


def thread_cpu_s(pid: int, proc_root: Path = Path("/proc")) -> dict[str, float]:
    """CPU seconds used so far by each thread name of process `pid` (empty when it is gone)."""
    out: dict[str, float] = {}
    try:
        tasks = list((proc_root / str(pid) / "task").iterdir())
    except OSError:
        return out
    for task in tasks:
        try:
            comm, cpu_s = parse_stat((task / "stat").read_text())
        except (OSError, ValueError, IndexError):
            continue
        out[comm] = round(out.get(comm, 0.0) + cpu_s, 2)
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))
