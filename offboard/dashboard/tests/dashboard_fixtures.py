"""Functions of the dashboard browser tests (imported by conftest.py and the tests; a unique module
name, since other components have a conftest.py of their own): the running quad-control and its
bench configuration (re-exported from offboard/quadcontrol/quadcontrol_harness, which tools
share), plus headless Debian chromium driven by Playwright. Everything listens on 127.0.0.1 only.
"""

from __future__ import annotations

from quadcontrol_harness.quad_control import (  # noqa: F401  (re-exported to the tests)
    KEY,
    REPO,
    QuadControl,
    quad_control_binary,
    write_config,
)

ARTIFACTS = REPO / "test-artifacts" / "dashboard"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
