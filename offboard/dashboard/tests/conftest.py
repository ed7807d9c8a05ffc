"""Pytest fixtures of the dashboard tests (helpers in dashboard_fixtures.py)."""

from __future__ import annotations

import os
import pathlib
import shutil

import pytest
from dashboard_fixtures import (
    ARTIFACTS,
    CHROMIUM,
    CHROMIUM_ARGS,
    KEY,
    QuadControl,
    quad_control_binary,
    write_config,
)


@pytest.fixture(scope="module")
def binary() -> pathlib.Path:
    b = quad_control_binary()
    if b is None:
        pytest.skip("quad-control is not built (make build, or set QUAD_CONTROL_BIN)")
    return b


@pytest.fixture(scope="module")
def firmware():
    from quadcontrol_harness.firmware_double import FirmwareDouble
    from rgbd_protocol.control_bridge import WifiBridgeEmulator

    double = FirmwareDouble(KEY)
    bridge = WifiBridgeEmulator(double.transact).start()
    yield double, bridge
    bridge.close()


@pytest.fixture(scope="module")
def quad_control(binary, firmware, tmp_path_factory):
    _, bridge = firmware
    cfg = write_config(tmp_path_factory.mktemp("qc"), bridge.port)
    qc = QuadControl(binary, ["--config", str(cfg), "--port", "0"])
    yield qc
    qc.stop()


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    if not os.access(CHROMIUM, os.X_OK) or shutil.which("chromium") is None:
        pytest.skip("Debian chromium is not installed (deps/apt/dashboard.txt)")
    sync_api = pytest.importorskip("playwright.sync_api")
    profile = tmp_path_factory.mktemp("chromium-profile")
    with sync_api.sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            str(profile),
            executable_path=CHROMIUM,
            headless=True,
            args=CHROMIUM_ARGS,
            viewport={"width": 1400, "height": 1000},
        )
        yield context
        context.close()


@pytest.fixture()
def artifacts() -> pathlib.Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS
