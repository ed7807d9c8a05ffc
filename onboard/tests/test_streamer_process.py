"""rgbd-streamer as a process: truthful --help, bad configuration, searching for the ground station
forever and stopping cleanly on SIGTERM, and the installer's staged layout + systemd unit.

Uses the binary from $BUILD_DIR (default build/, what `make test` builds). Processes listen/connect
on loopback only and are stopped by PID."""

import os
import re
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("BUILD_DIR", ROOT / "build"))
if not BUILD.is_absolute():
    BUILD = ROOT / BUILD
BINARY = BUILD / "bin" / "rgbd-streamer"
DESK = ROOT / "tests" / "data" / "fr1_desk_9frames"

pytestmark = pytest.mark.skipif(not BINARY.exists(), reason=f"{BINARY} not built")


def run(*args, **kwargs):
    return subprocess.run(
        [str(BINARY), *args], capture_output=True, text=True, timeout=30, **kwargs
    )


def two_free_ports() -> tuple[int, int]:
    """Both probes stay bound until both are read, so the kernel cannot hand the same port twice."""
    with socket.socket() as a, socket.socket() as b:
        a.bind(("127.0.0.1", 0))
        b.bind(("127.0.0.1", 0))
        return a.getsockname()[1], b.getsockname()[1]


def write_key(
    path: Path, text: str = "00112233445566778899aabbccddeeff\n", mode: int = 0o600
) -> Path:
    path.write_text(text)
    os.chmod(path, mode)
    return path


def test_help_lists_every_option_and_each_is_honoured():
    help_text = run("--help").stdout
    options = re.findall(r"--([a-z0-9-]+)", help_text)
    for expected in [
        "config",
        "print-config",
        "source",
        "tum-dir",
        "host",
        "rgb-port",
        "depth-port",
        "depth-encoding",
        "rgb-encoding",
        "jpeg-quality",
        "stats-period",
        "log-level",
    ]:
        assert expected in options
    # GIVEN overrides on the command line WHEN printing the config THEN they are what is loaded
    out = run(
        "--print-config",
        "--source",
        "tum",
        "--tum-dir",
        str(DESK),
        "--host",
        "10.1.2.3",
        "--rgb-port",
        "7000",
        "--depth-port",
        "7001",
        "--depth-encoding",
        "zstd-delta",
        "--rgb-encoding",
        "jpeg",
        "--jpeg-quality",
        "80",
        "--stats-period",
        "2",
        "--max-frames",
        "5",
        "--tum-fps",
        "15",
        "--tum-loop",
        "false",
    )
    assert out.returncode == 0, out.stderr
    cfg = dict(line.split(": ", 1) for line in out.stdout.strip().splitlines())
    assert cfg["source"] == "tum" and cfg["host"] == "10.1.2.3"
    assert (cfg["rgb_port"], cfg["depth_port"]) == ("7000", "7001")
    assert (cfg["depth_encoding"], cfg["rgb_encoding"], cfg["jpeg_quality"]) == (
        "zstd-delta",
        "jpeg",
        "80",
    )
    assert (cfg["stats_period_s"], cfg["max_frames"], cfg["tum_fps"], cfg["tum_loop"]) == (
        "2",
        "5",
        "15",
        "false",
    )


@pytest.mark.parametrize(
    "text,message",
    [
        ("sorce: tum\n", "unknown key 'sorce'"),
        ("depth_encoding: png\n", "depth_encoding"),
        ("rgb_port: 5601\n", "distinct"),
    ],
)
def test_bad_configuration_exits_2_with_the_reason(tmp_path, text, message):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    out = run("--config", str(cfg))
    assert out.returncode == 2
    assert message in out.stderr


def test_missing_kinect_is_a_clear_start_up_error(tmp_path):
    out = run(
        "--source",
        "openni2",
        "--host",
        "127.0.0.1",
        "--stats-period",
        "0",
        "--stream-key-file",
        str(write_key(tmp_path / "stream.key")),
    )
    assert out.returncode == 1
    assert "OpenNI2" in out.stderr


@pytest.mark.parametrize(
    "setup,message",
    [
        (lambda d: d / "absent.key", "No such file"),
        (
            lambda d: write_key(d / "open.key", mode=0o644),
            "accessible by group or others (mode 0644); `chmod 600",
        ),
        (lambda d: write_key(d / "short.key", "abcd\n"), "32 hex digits"),
        (lambda d: write_key(d / "zero.key", "0" * 32 + "\n"), "all zeros"),
    ],
)
def test_missing_or_unsafe_stream_key_exits_2_with_the_reason(tmp_path, setup, message):
    # GIVEN a stream key file that is absent, readable by others, malformed or a zero template
    key = setup(tmp_path)
    # WHEN the streamer starts THEN it refuses at once, naming the file and the fix
    out = run(
        "--source",
        "tum",
        "--tum-dir",
        str(DESK),
        "--host",
        "127.0.0.1",
        "--stream-key-file",
        str(key),
        "--config",
        "/dev/null",
    )
    assert out.returncode == 2, out.stderr
    assert str(key) in out.stderr and message in out.stderr


def test_searches_for_the_ground_station_forever_and_stops_on_sigterm(tmp_path):
    rgb_port, depth_port = two_free_ports()  # nobody listens here
    proc = subprocess.Popen(
        [
            str(BINARY),
            "--source",
            "tum",
            "--tum-dir",
            str(DESK),
            "--tum-loop",
            "true",
            "--host",
            "127.0.0.1",
            "--rgb-port",
            str(rgb_port),
            "--depth-port",
            str(depth_port),
            "--stats-period",
            "0.5",
            "--stream-key-file",
            str(write_key(tmp_path / "stream.key")),
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(2.0)
        assert proc.poll() is None, "must keep searching, not exit"
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
    assert proc.returncode == 0, err
    assert "retrying" in err and "connection refused" in err.lower()
    assert "captured" in err  # periodic counters line
    assert "signal 15: stopping" in err


def test_installer_stages_binary_config_and_a_valid_unit(tmp_path):
    env = dict(os.environ, DESTDIR=str(tmp_path), BUILD_DIR=str(BUILD))
    out = subprocess.run(
        [str(ROOT / "onboard" / "install.sh")], env=env, capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stdout + out.stderr
    binary = tmp_path / "usr/bin/rgbd-streamer"
    unit = tmp_path / "lib/systemd/system/rgbd-streamer.service"
    assert binary.exists() and (tmp_path / "etc/rgbd-streamer/rgbd-streamer.yaml").exists()
    text = unit.read_text()
    for line in [
        "Restart=always",
        "User=rgbd",
        "After=network-online.target",
        "WantedBy=multi-user.target",
    ]:
        assert line in text
    # Idempotent: a second run keeps the (possibly edited) config.
    (tmp_path / "etc/rgbd-streamer/rgbd-streamer.yaml").write_text("host: 10.0.0.7\n")
    again = subprocess.run(
        [str(ROOT / "onboard" / "install.sh")], env=env, capture_output=True, text=True, timeout=60
    )
    assert again.returncode == 0
    assert (tmp_path / "etc/rgbd-streamer/rgbd-streamer.yaml").read_text() == "host: 10.0.0.7\n"
    if shutil.which("systemd-analyze"):
        checked = tmp_path / "rgbd-streamer.service"
        checked.write_text(text.replace("ExecStart=/usr/bin/rgbd-streamer", f"ExecStart={binary}"))
        verify = subprocess.run(
            ["systemd-analyze", "verify", str(checked)], capture_output=True, text=True, timeout=60
        )
        assert verify.returncode == 0, verify.stderr
