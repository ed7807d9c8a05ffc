"""quad-control's SLAM link to the real slam-server (offboard/slamlink) over loopback TCP: TUM
replay frames go out as RgbdFrame, PoseUpdates come back and drive the pose on the dashboard API.
Also: with slam-server down, frames still reach the dashboard and the link reports why.
Skipped when slam-server is not built (SLAM_SERVER=path overrides build/bin/slam-server).
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


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def state(qc: QuadControl) -> dict:
    with urllib.request.urlopen(qc.url + "api/state", timeout=5) as r:
        return json.load(r)


def config(tmp_path, port: int):
    cfg = tmp_path / "slam.json"
    cfg.write_text(
        json.dumps(
            {
                "dashboard": {"port": 0},
                "firmware": {"enabled": False},
                "slam": {"mode": "server", "host": "127.0.0.1", "port": port, "timeout_ms": 20000},
            }
        )
    )
    return cfg


def test_poses_from_slam_server(binary, tmp_path):
    server = os.environ.get("SLAM_SERVER", str(REPO / "build" / "bin" / "slam-server"))
    if not os.access(server, os.X_OK):
        pytest.skip(f"{server} not built")
    port = free_port()
    proc = subprocess.Popen(
        [server, "--bind", "127.0.0.1", "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    qc = None
    try:
        qc = QuadControl(binary, ["--config", str(config(tmp_path, port)), "--port", "0"])
        deadline = time.monotonic() + 90
        s = {}
        while time.monotonic() < deadline:
            s = state(qc)
            if s["slam"]["processed"] >= 3 and s["pose"] is not None:
                break
            time.sleep(0.5)
        assert s["slam"]["processed"] >= 3, s["slam"]
        assert s["slam"]["link"].startswith("slam-server at 127.0.0.1")
        assert s["pose"] is not None and s["slam"]["state"] in (
            "tracking",
            "initialising",
            "lost",
            "relocalised",
        )
    finally:
        if qc:
            qc.stop()
        proc.terminate()  # by PID
        proc.wait(timeout=30)


def test_frames_flow_while_slam_server_is_down(binary, tmp_path):
    qc = QuadControl(binary, ["--config", str(config(tmp_path, free_port())), "--port", "0"])
    try:
        deadline = time.monotonic() + 30
        s = {}
        while time.monotonic() < deadline:
            s = state(qc)
            if s["stream"]["frames"] >= 5 and "cannot connect" in s["slam"]["error"]:
                break
            time.sleep(0.3)
        assert s["stream"]["frames"] >= 5
        assert "cannot connect" in s["slam"]["error"]
        assert s["slam"]["processed"] == 0
    finally:
        qc.stop()
