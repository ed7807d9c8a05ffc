"""The live path: the real rgbd-streamer (TUM source, loopback) -> offboard/receiver inside
quad-control -> dashboard API. Skipped when rgbd-streamer is not built. Processes are stopped by
PID.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import time
import urllib.request

import pytest
from dashboard_fixtures import REPO, QuadControl


def two_free_ports() -> tuple[int, int]:
    """Both probes stay bound until both are read, so the kernel cannot hand the same port twice."""
    with socket.socket() as a, socket.socket() as b:
        a.bind(("127.0.0.1", 0))
        b.bind(("127.0.0.1", 0))
        return a.getsockname()[1], b.getsockname()[1]


def streamer_binary() -> str | None:
    for c in (
        os.environ.get("RGBD_STREAMER_BIN", ""),
        str(REPO / "build" / "bin" / "rgbd-streamer"),
    ):
        if c and os.access(c, os.X_OK):
            return c
    return None


def test_frames_from_rgbd_streamer_reach_the_dashboard(binary, tmp_path):
    streamer = streamer_binary()
    if streamer is None:
        pytest.skip("rgbd-streamer is not built (make build, or set RGBD_STREAMER_BIN)")
    rgb_port, depth_port = two_free_ports()
    key = (
        tmp_path / "stream.key"
    )  # the craft's stream key: both ends read the same file (mode 0600)
    key.write_text("5c0ffee5" * 4 + "\n")
    key.chmod(0o600)
    cfg = tmp_path / "live.json"
    cfg.write_text(
        json.dumps(
            {
                "dashboard": {"port": 0},
                "stream": {
                    "source": "receiver",
                    "bind_address": "127.0.0.1",
                    "rgb_port": rgb_port,
                    "depth_port": depth_port,
                    "key_file": str(key),
                },
                "slam": {"mode": "in-process"},
                "firmware": {"enabled": False},
            }
        )
    )
    qc = QuadControl(binary, ["--config", str(cfg), "--port", "0"])
    proc = subprocess.Popen(
        [
            streamer,
            "--source",
            "tum",
            "--tum-dir",
            str(REPO / "tests/data/fr1_xyz_first30"),
            "--host",
            "127.0.0.1",
            "--rgb-port",
            str(rgb_port),
            "--depth-port",
            str(depth_port),
            "--stats-period",
            "0",
            "--stream-key-file",
            str(key),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        state = {}
        while time.monotonic() < deadline:
            with urllib.request.urlopen(qc.url + "api/state", timeout=5) as r:
                state = json.load(r)
            if state["stream"]["frames"] >= 5 and state["slam"]["processed"] >= 1:
                break
            time.sleep(0.3)
        assert state["stream"]["frames"] >= 5, state["stream"]
        assert "rgbd-streamer" in state["stream"]["source"]
        assert state["slam"]["processed"] >= 1
        with urllib.request.urlopen(qc.url + "api/rgb.jpg", timeout=5) as r:
            assert r.headers["Content-Type"] == "image/jpeg" and len(r.read()) > 1000
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        qc.stop()
