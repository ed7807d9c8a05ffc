"""Descriptor exhaustion on the whole quad-control process: with its descriptor limit lowered
(RLIMIT_NOFILE in the child, set before exec) and a flood of idle dashboard connections, no thread
spins (CPU time per thread from /proc, not wall time), the replay keeps reading frames (the frame
thread needs descriptors too) and the operator still gets /api/state. An accept loop without
back-off takes a whole core retrying accept() and new clients time out. Loopback only; stopped by
PID."""

from __future__ import annotations

import json
import os
import resource
import socket
import time
import urllib.request

from dashboard_fixtures import QuadControl

FD_LIMIT = 64  # quad-control needs ~20 at start-up; the flood takes the rest
FLOOD_CONNECTIONS = 200
WINDOW_S = 3.0
CLK_TCK = os.sysconf("SC_CLK_TCK")


def thread_cpu_s(pid: int) -> dict[int, float]:
    """utime + stime of every thread of `pid`, seconds."""
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            out[int(tid)] = (int(fields[11]) + int(fields[12])) / CLK_TCK
        except (FileNotFoundError, ProcessLookupError):
            pass
    return out


def state(url: str, timeout_s: float) -> dict:
    with urllib.request.urlopen(url + "api/state", timeout=timeout_s) as r:
        return json.load(r)


def test_descriptor_limit_does_not_spin_or_lock_out(binary):
    def low_fd_limit():
        resource.setrlimit(resource.RLIMIT_NOFILE, (FD_LIMIT, FD_LIMIT))

    # GIVEN quad-control (TUM replay, no craft, no slam-server) limited to 64 descriptors
    qc = QuadControl(binary, ["--no-firmware", "--port", "0"], preexec_fn=low_fd_limit)
    port = int(qc.url.rstrip("/").rsplit(":", 1)[1])
    flood: list[socket.socket] = []
    try:
        # the process's own load first (the replay decodes 30 fps), as the reference
        quiet0 = thread_cpu_s(qc.proc.pid)
        time.sleep(WINDOW_S)
        quiet = sum(thread_cpu_s(qc.proc.pid).values()) - sum(quiet0.values())
        frames_before = state(qc.url, 5)["stream"]["frames"]
        # WHEN 200 idle connections are opened and kept
        for _ in range(FLOOD_CONNECTIONS):
            s = socket.socket()
            s.settimeout(2)
            try:
                s.connect(("127.0.0.1", port))
            except OSError:
                s.close()
                continue
            flood.append(s)
        time.sleep(0.5)
        before = thread_cpu_s(qc.proc.pid)
        time.sleep(WINDOW_S)
        after = thread_cpu_s(qc.proc.pid)
        log_tail = "".join(line for line in qc.log[-40:] if "WARN" not in line)[-2000:]
        assert qc.proc.poll() is None, f"quad-control died (exit {qc.proc.returncode}):\n{log_tail}"
        busiest, busiest_tid = max((after[t] - before.get(t, 0.0), t) for t in after)
        total = sum(after.values()) - sum(before.values())
        name = open(f"/proc/{qc.proc.pid}/task/{busiest_tid}/comm").read().strip()
        print(
            f"flood of {len(flood)}: busiest thread ({name}) {busiest:.2f} s, "
            f"process {total:.2f} s of CPU in {WINDOW_S} s (without the flood {quiet:.2f} s)"
        )
        # THEN no thread spins (the frame thread decodes 30 fps: well under half a core)
        assert busiest < 0.5 * WINDOW_S, f"a thread used {busiest:.2f} s of CPU in {WINDOW_S} s"
        assert total < quiet + 0.5, f"the flood added {total - quiet:.2f} s of CPU in {WINDOW_S} s"
        # AND the operator still gets the state (an idle connection is evicted for it)
        s = state(qc.url, 5)
        # AND the replay kept reading frames during the flood
        assert s["stream"]["frames"] > frames_before, s["stream"]
        assert not s["stream"]["error"], s["stream"]
    finally:
        for s in flood:
            s.close()
        qc.stop()
