"""Fixtures shared by the slam_study tests: repo data paths and the fake slam-eval."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

kRepo = Path(__file__).resolve().parents[4]
kTestData = kRepo / "tests" / "data"


@pytest.fixture
def fr1_xyz30() -> Path:
    return kTestData / "fr1_xyz_first30"


@pytest.fixture
def fr1_desk9() -> Path:
    return kTestData / "fr1_desk_9frames"


@pytest.fixture
def fake_slam_eval(tmp_path: Path) -> Path:
    """An executable with slam-eval's interface (tests/fake_slam_eval.py) run by this Python."""
    script = tmp_path / "slam-eval"
    pythonpath = os.pathsep.join([str(kRepo / "offboard" / "study")])
    script.write_text(
        "#!/bin/sh\n"
        f"PYTHONPATH='{pythonpath}' exec '{sys.executable}' "
        f"'{Path(__file__).parent / 'fake_slam_eval.py'}' \"$@\"\n"
    )
    script.chmod(0o755)
    return script
