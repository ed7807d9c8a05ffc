"""The real quad-control and slam-server with the SLAM link severed for 1 s.

GIVEN quad-control replaying tests/data/fr1_xyz_first30 (no firmware) to slam-server through the
HIL rig's LinkProxy, WHEN the proxy severs the link (every connection reset, the port refusing) and
restores it 1 s later, THEN quad-control logs the disconnect with its cause and reconnects with the
same map id, slam-server resumes the same map (no new map), and quad-control's /api/state counts 1
map started, >= 1 resume, >= 1 disconnect. Processes are stopped by PID; loopback only.
Skipped when the binaries are not built.
"""

import json
import os
import re
import signal
import subprocess
import time
import urllib.request
from pathlib import Path

import pytest
from hilrig.link_proxy import LinkProxy
from hilrig.slam_flight import free_port

REPO = Path(__file__).resolve().parents[2]
BIN = REPO / "build" / "bin"
SLAM_SERVER = Path(os.environ.get("SLAM_SERVER", BIN / "slam-server"))
QUAD_CONTROL = Path(os.environ.get("QUAD_CONTROL_BIN", BIN / "quad-control"))
DEADLINE_S = 60.0

pytestmark = pytest.mark.skipif(
    not (SLAM_SERVER.exists() and QUAD_CONTROL.exists()),
    reason="slam-server / quad-control not built",
)


def wait_for(path: Path, pattern: str, deadline: float) -> re.Match:
    while True:
        m = re.search(pattern, path.read_text(errors="replace"))
        if m:
            return m
        assert time.monotonic() < deadline, (
            f"'{pattern}' not in {path.name}:\n{path.read_text()[-3000:]}"
        )
        time.sleep(0.1)


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_severed_slam_link_resumes_the_same_map(tmp_path):
    ss_log, qc_log = tmp_path / "slam-server.log", tmp_path / "quad-control.log"
    port = free_port()
    ss = subprocess.Popen(
        [
            str(SLAM_SERVER),
            "--bind",
            "127.0.0.1",
            "--port",
            str(port),
            "--features",
            "orb",
            "--backend",
            "vo",
        ],
        stderr=open(ss_log, "w"),
    )
    proxy = None
    qc = None
    try:
        deadline = time.monotonic() + DEADLINE_S
        wait_for(ss_log, "listening", deadline)
        proxy = LinkProxy(port)
        cfg = tmp_path / "quad-control.json"
        cfg.write_text(
            json.dumps({"slam": {"mode": "server", "host": "127.0.0.1", "port": proxy.port}})
        )
        qc = subprocess.Popen(
            [
                str(QUAD_CONTROL),
                "--no-firmware",
                "--config",
                str(cfg),
                "--port",
                "0",
                "--tum",
                str(REPO / "tests" / "data" / "fr1_xyz_first30"),
            ],
            stdout=open(qc_log, "w"),
            stderr=subprocess.STDOUT,
        )
        dash = wait_for(qc_log, r"dashboard on http://127\.0\.0\.1:(\d+)/", deadline).group(1)
        sid = wait_for(
            qc_log,
            r"SLAM link: connected to .*: map ([0-9a-f]+) started \(new\)",
            deadline,
        ).group(1)
        wait_for(ss_log, r"slam-server: \d+ frames|map [0-9a-f]+ new", deadline)
        time.sleep(2.0)  # some frames into the map
        proxy.sever()
        time.sleep(1.0)
        proxy.restore()
        wait_for(
            qc_log,
            rf"map {sid} resumed \(world frame kept",
            time.monotonic() + DEADLINE_S,
        )
        wait_for(ss_log, rf"map {sid} resumed", time.monotonic() + DEADLINE_S)
        with urllib.request.urlopen(f"http://127.0.0.1:{dash}/api/state", timeout=10) as r:
            slam = json.load(r)["slam"]
    finally:
        if qc is not None:
            stop(qc)
        if proxy is not None:
            proxy.close()
        stop(ss)
    qc_text, ss_text = qc_log.read_text(), ss_log.read_text()
    assert re.search(r"SLAM link: disconnected: .+; reconnecting to resume map " + sid, qc_text)
    assert len(re.findall(r"map [0-9a-f]+ started \(new\)", ss_text)) == 1, ss_text
    assert re.search(r"closed: .+; \d+ frames on this connection, map " + sid, ss_text)
    assert slam["sessions_started"] == 1 and slam["resumes"] >= 1 and slam["disconnects"] >= 1, slam
    assert slam["session_id"] == sid
