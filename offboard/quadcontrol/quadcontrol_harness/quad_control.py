"""quad-control as a child process: `QuadControl` starts it and waits for its dashboard URL,
`write_config` writes the bench configuration (TUM replay tests/data/fr1_xyz_first30, firmware at
a given loopback port), `KEY` is the test control-link key. The process is stopped by its PID.
"""

from __future__ import annotations

import json
import os
import pathlib
import queue
import re
import subprocess
import threading

REPO = pathlib.Path(__file__).resolve().parents[3]
KEY = bytes(range(16))  # test key (the protocol/control golden-vector key), never a craft's
START_TIMEOUT_S = 60.0  # quad-control prints its dashboard URL once the SLAM front-end is set up


def quad_control_binary() -> pathlib.Path | None:
    candidates = [
        os.environ.get("QUAD_CONTROL_BIN", ""),
        str(REPO / "build" / "bin" / "quad-control"),
    ]
    for c in candidates:
        if c and os.access(c, os.X_OK):
            return pathlib.Path(c)
    return None


class QuadControl:
    """A running quad-control process; `url` is its dashboard."""

    def __init__(self, binary: pathlib.Path, args: list[str], preexec_fn=None) -> None:
        self.proc = subprocess.Popen(
            [str(binary), *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            preexec_fn=preexec_fn,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.log: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()
        self.url = self._wait_url()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.log.append(line)
            self.lines.put(line)

    def _wait_url(self) -> str:
        import time

        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.5)
            except queue.Empty:
                if self.proc.poll() is not None:
                    break
                continue
            m = re.search(r"dashboard on (http://127\.0\.0\.1:\d+/)", line)
            if m:
                return m.group(1)
        self.stop()
        raise RuntimeError("quad-control did not start:\n" + "".join(self.log))

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()  # by PID (Popen), never by name
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def write_config(tmp: pathlib.Path, bridge_port: int) -> pathlib.Path:
    # A hand-held camera (the TUM replay) cannot climb, and on the shared 2-core machine the SLAM
    # front-end answers about once a second, so this bench configuration holds just above the
    # replay's height and tolerates slow poses. Everything else is the shipped default.
    cfg = {
        "dashboard": {"bind_address": "127.0.0.1", "port": 0},
        "stream": {
            "source": "tum",
            "tum_folder": str(REPO / "tests/data/fr1_xyz_first30"),
            "loop": "bounce",
        },
        "slam": {"mode": "in-process"},
        "firmware": {
            "host": "127.0.0.1",
            "port": bridge_port,
            "key_hex": KEY.hex(),
            "timeout_ms": 200,
        },
        "camera": {"mount_pitch_down_deg": 0.0},
        "controller": {
            "hold_height_m": 1.0,
            "takeoff_reached_tolerance_m": 0.5,
            "pose_timeout_ms": 8000.0,
            "lost_hold_ms": 8000.0,
        },
    }
    path = tmp / "quad-control-test.json"
    path.write_text(json.dumps(cfg, indent=2))
    return path
