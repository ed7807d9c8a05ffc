"""An installed quad-control runs from any directory: `cmake --install <build>
--component quad-control` into a temporary prefix, then the installed binary, started from an
unrelated working directory, finds its dashboard files and the default TUM replay under
<prefix>/share/rgbdquad (app/data_paths.hpp), serves /api/state and the page on loopback, and
names every path it tried when a data folder is missing. The build folder is $RGBD_BUILD_DIR
(default <repo>/build); skipped, with the reason, when quad-control is not built there. The
process is stopped by its PID.
"""

from __future__ import annotations

import json
import os
import pathlib
import queue
import re
import shutil
import socket
import subprocess
import threading
import time
import urllib.request

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
BUILD = pathlib.Path(os.environ.get("RGBD_BUILD_DIR", REPO / "build"))
START_TIMEOUT_S = 60.0  # the machine may be loaded; quad-control prints its URL once serving

pytestmark = pytest.mark.skipif(
    not os.access(BUILD / "bin" / "quad-control", os.X_OK)
    or not (BUILD / "cmake_install.cmake").is_file(),
    reason=f"quad-control not built in {BUILD} (build it, or set RGBD_BUILD_DIR)",
)


@pytest.fixture(scope="module")
def prefix(tmp_path_factory) -> pathlib.Path:
    cmake = shutil.which("cmake")
    if cmake is None:
        pytest.skip("cmake not on PATH")
    p = tmp_path_factory.mktemp("prefix")
    subprocess.run(
        [cmake, "--install", str(BUILD), "--prefix", str(p), "--component", "quad-control"],
        check=True,
        capture_output=True,
        text=True,
        timeout=120,
    )
    return p


@pytest.fixture()
def elsewhere(tmp_path) -> pathlib.Path:
    """A working directory with nothing of the project in or above it."""
    d = tmp_path / "cwd"
    d.mkdir()
    return d


def unused_loopback_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_install_puts_the_binary_its_data_and_the_config_template_under_the_prefix(prefix):
    share = prefix / "share" / "rgbdquad"
    for f in ["bin/quad-control"]:
        assert os.access(prefix / f, os.X_OK), f
    for f in [
        "dashboard/index.html",
        "dashboard/app.js",
        "data/fr1_xyz_first30/rgb.txt",
        "data/fr1_xyz_first30/depth.txt",
        "config/quad-control.json",
    ]:
        assert (share / f).is_file(), f
    assert len(list((share / "data/fr1_xyz_first30/rgb").iterdir())) == 30


def test_installed_help_names_the_installed_locations(prefix, elsewhere):
    r = subprocess.run(
        [str(prefix / "bin/quad-control"), "--help"],
        cwd=elsewhere,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 0, r.stderr
    assert "share/rgbdquad/config/quad-control.json" in r.stdout
    assert "share/rgbdquad/{dashboard,data/fr1_xyz_first30}" in r.stdout


def test_installed_binary_takes_its_data_from_the_prefix_from_any_directory(prefix, elsewhere):
    r = subprocess.run(
        [str(prefix / "bin/quad-control"), "--no-firmware", "--print-config"],
        cwd=elsewhere,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("quad-control: configuration "))
    config = json.loads(line.removeprefix("quad-control: configuration "))
    share = (prefix / "share" / "rgbdquad").resolve()
    assert pathlib.Path(config["dashboard"]["static_dir"]) == share / "dashboard"
    assert pathlib.Path(config["stream"]["tum_folder"]) == share / "data/fr1_xyz_first30"
    assert "control_spec" not in config["firmware"]  # compiled in, no file


def test_installed_binary_serves_the_dashboard_and_state(prefix, elsewhere):
    # SLAM over the link to a port nobody listens on: frames and state still flow, no SLAM load.
    cfg = elsewhere / "qc.json"
    cfg.write_text(
        json.dumps(
            {"slam": {"mode": "server", "host": "127.0.0.1", "port": unused_loopback_port()}}
        )
    )
    proc = subprocess.Popen(
        [
            str(prefix / "bin/quad-control"),
            "--config",
            str(cfg),
            "--no-firmware",
            "--no-record",
            "--port",
            "0",
        ],
        cwd=elsewhere,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: queue.Queue[str] = queue.Queue()
    log: list[str] = []

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            log.append(line)
            lines.put(line)

    threading.Thread(target=pump, daemon=True).start()
    try:
        url = None
        deadline = time.monotonic() + START_TIMEOUT_S
        while url is None and time.monotonic() < deadline and proc.poll() is None:
            try:
                m = re.search(r"dashboard on (http://127\.0\.0\.1:\d+/)", lines.get(timeout=0.5))
            except queue.Empty:
                continue
            url = m.group(1) if m else None
        assert url, "quad-control did not start:\n" + "".join(log)
        assert any("data/fr1_xyz_first30" in x and "stream from" in x for x in log), "".join(log)
        with urllib.request.urlopen(url + "api/state", timeout=10) as r:
            assert r.status == 200
            state = json.loads(r.read())
        assert isinstance(state, dict) and state
        with urllib.request.urlopen(url, timeout=10) as r:
            page = r.read().decode()
        assert page == (prefix / "share/rgbdquad/dashboard/index.html").read_text()
    finally:
        if proc.poll() is None:
            proc.terminate()  # by PID (Popen), never by name
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def test_a_missing_data_folder_is_a_clear_error_naming_the_paths_tried(prefix, tmp_path, elsewhere):
    # A copy of the installed tree without its dashboard files.
    copy = tmp_path / "broken"
    shutil.copytree(prefix, copy)
    shutil.rmtree(copy / "share/rgbdquad/dashboard")
    r = subprocess.run(
        [str(copy / "bin/quad-control"), "--no-firmware", "--print-config"],
        cwd=elsewhere,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 2, r.stdout + r.stderr
    assert "dashboard static files not found" in r.stderr
    assert str((copy / "share/rgbdquad/dashboard").resolve()) in r.stderr
    assert "dashboard.static_dir" in r.stderr
