"""`make hil` must fail, not skip, when a part of the rig is missing.

Runs one HIL scenario in a child pytest with RGBD_BUILD_DIR pointing at an empty folder, so
slam-eval cannot be found: with HIL_STRICT=1 (what hil/run.sh sets) the run fails and names the
missing part; with HIL_STRICT=0 the same scenario is skipped with the same reason.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCENARIO = "hil/scenarios/test_scenario_slam_replay.py"


def run_scenario(tmp_path: Path, strict: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, RGBD_BUILD_DIR=str(tmp_path / "no-build"), HIL_STRICT=strict)
    env.pop("RGBD_BIN_DIR", None)
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-m",
            "hil",
            "-rs",
            "-q",
            "-p",
            "no:cacheprovider",
            SCENARIO,
        ],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


# A skip in a fixture becomes an error of the test's set-up, one in the test body a failure.
@pytest.mark.parametrize(
    "strict,code,words", [("1", 1, ("error", "failed")), ("0", 0, ("skipped",))]
)
def test_missing_part_fails_under_make_hil_and_skips_otherwise(tmp_path, strict, code, words):
    out = run_scenario(tmp_path, strict)
    text = out.stdout + out.stderr
    assert out.returncode == code, text[-2000:]
    assert any(w in text.splitlines()[-1] for w in words), text[-2000:]
    assert "slam-eval is not built" in text, text[-2000:]
    if strict == "1":
        assert "HIL_STRICT" in text, text[-2000:]
