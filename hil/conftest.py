"""pytest configuration of hil/: the `hil` marker.

Scenarios marked `@pytest.mark.hil` fly simulated flights that take tens of seconds to minutes, so
the default run (`make test`) deselects them; `make hil` (hil/run.sh) runs them with `-m hil`.
Setting RGBD_HIL=1 also keeps them.

`make hil` (hil/run.sh) also sets HIL_STRICT=1: a scenario that would skip because a part is not
built or not installed (fw_sim, the firmware image, slam-eval, rgbd-streamer, fakenect, ...) fails
instead, with the skip's reason, so a missing part can never turn a HIL run green. A developer
running a subset without every part can set HIL_STRICT=0. Expected failures (xfail) are untouched.
"""

import os

import pytest


def pytest_configure(config):
    config.addinivalue_line("markers", "hil: slow hardware-in-loop scenario (run by `make hil`)")


def pytest_collection_modifyitems(config, items):
    if "hil" in (config.getoption("-m") or "") or os.environ.get("RGBD_HIL") == "1":
        return
    kept, dropped = [], []
    for item in items:
        (dropped if item.get_closest_marker("hil") else kept).append(item)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept


def _strict() -> bool:
    return os.environ.get("HIL_STRICT") == "1"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if not (_strict() and report.skipped and item.get_closest_marker("hil")):
        return
    if hasattr(report, "wasxfail"):  # an expected failure is a result, not a missing part
        return
    reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
    report.outcome = "failed"
    report.longrepr = (
        f"HIL_STRICT: a part of the rig is missing, so this scenario cannot run: {reason}"
    )
