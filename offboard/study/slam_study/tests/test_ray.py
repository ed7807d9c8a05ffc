"""The sweep on a Ray cluster: a private head node on loopback (1 CPU), started and stopped by
this test. The node runs in its own session; teardown signals that process group and then any
process left in the session, by PID (never `ray stop`, which would stop every Ray on the host).

Costs ~15-30 s on 2 cores (Ray start-up), so it is opt-in for `make test`: it runs when
SLAM_STUDY_RAY_TEST=1 (offboard/study/study.sh sets it) and is skipped with that reason otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from slam_study import cli

kRayStartTimeoutS = 120.0  # a cold Ray head takes ~10-20 s on 2 busy cores

pytestmark = pytest.mark.skipif(
    os.environ.get("SLAM_STUDY_RAY_TEST") != "1",
    reason="Ray cluster test is opt-in (SLAM_STUDY_RAY_TEST=1; "
    "offboard/study/study.sh runs it): ~20 s of Ray start-up",
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _session_pids(sid: int) -> list[int]:
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid:  # field 6 of stat (session id), after pid and (comm)
            pids.append(int(entry.name))
    return pids


@pytest.fixture
def ray_head():
    ray_bin = Path(sys.executable).parent / "ray"
    if not ray_bin.exists():
        pytest.skip("ray is not installed in this Python environment")
    port = _free_port()
    temp_dir = tempfile.mkdtemp(prefix="rs", dir="/tmp")  # short: Ray's socket paths < 108 chars
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    log = open(Path(temp_dir) / "head.log", "w")  # noqa: SIM115 - open for the node's lifetime
    head = subprocess.Popen(
        [
            str(ray_bin),
            "start",
            "--head",
            "--block",
            "--port",
            str(port),
            "--node-ip-address",
            "127.0.0.1",
            "--num-cpus",
            "1",
            "--include-dashboard=false",
            "--disable-usage-stats",
            "--temp-dir",
            temp_dir,
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        env=env,
    )
    address = f"127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + kRayStartTimeoutS
        while time.monotonic() < deadline:
            if head.poll() is not None:
                pytest.fail(f"ray head exited: {(Path(temp_dir) / 'head.log').read_text()[-2000:]}")
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.5)
        else:
            pytest.fail("ray head did not open its port in time")
        yield address
    finally:
        sid = head.pid
        try:
            os.killpg(sid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        try:
            head.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
        for _ in range(20):
            left = _session_pids(sid)
            if not left:
                break
            for pid in left:
                try:
                    os.kill(pid, signal.SIGKILL if _ > 10 else signal.SIGTERM)
                except ProcessLookupError:
                    pass
            time.sleep(0.5)
        log.close()
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_sweep_on_a_local_ray_cluster(ray_head, tmp_path, fr1_desk9, fake_slam_eval, monkeypatch):
    monkeypatch.setenv("RAY_USAGE_STATS_ENABLED", "0")
    out = tmp_path / "report"
    assert (
        cli.main(
            [
                "run",
                "--data",
                str(fr1_desk9),
                "--out",
                str(out),
                "--slam-eval",
                str(fake_slam_eval),
                "--features",
                "sift,orb",
                "--backends",
                "vo",
                "--k",
                "1",
                "--ray",
                ray_head,
            ]
        )
        == 0
    )
    for cfg in ("sift-vo-k1", "orb-vo-k1"):
        result = json.loads((out / "runs" / "fr1_desk_9frames" / cfg / "result.json").read_text())
        assert result["status"] == "ok", result
        assert (out / "runs" / "fr1_desk_9frames" / cfg / "trajectory.tum").stat().st_size > 0
    assert "ray 127.0.0.1" in (out / "sweep.json").read_text()
    assert "Table 4.20a" in (out / "report.md").read_text()
