"""pytest configuration of hil/: the `hil` marker.

Scenarios marked `@pytest.mark.hil` fly simulated flights that take tens of seconds to minutes, so
the default run (`make test`) deselects them; `make hil` (hil/run.sh) runs them with `-m hil`.
Setting RGBD_HIL=1 also keeps them.
"""

import os


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
