"""Integration with the engine's real `slam-eval` (built by offboard/eval): a two-run sweep on the
9-frame fr1/desk excerpt, and our per-pair RPE against the RPE slam-eval reports itself.
Skipped, with the reason, when the binary is not built ($RGBD_BUILD_DIR, default <repo>/build)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from slam_study import cli, pairs, tum
from slam_study.tests.conftest import kRepo

kSlamEval = Path(os.environ.get("RGBD_BUILD_DIR", kRepo / "build")) / "bin" / "slam-eval"

pytestmark = pytest.mark.skipif(
    not os.access(kSlamEval, os.X_OK),
    reason=f"slam-eval not built at {kSlamEval} (set RGBD_BUILD_DIR)",
)


def test_sweep_with_real_slam_eval_matches_its_own_rpe(tmp_path, fr1_desk9):
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
                str(kSlamEval),
                "--features",
                "orb",
                "--backends",
                "vo",
                "--k",
                "1,2",
                "--jobs",
                "1",
                "--slam-eval-args",
                "--no-map --quiet",
            ]
        )
        == 0
    )
    run_dir = out / "runs" / "fr1_desk_9frames" / "orb-vo-k1"
    result = json.loads((run_dir / "result.json").read_text())
    assert result["status"] == "ok", result
    engine = json.loads((run_dir / "metrics.json").read_text())
    ours = pairs.motion_pairs(
        tum.Dataset.load(fr1_desk9).groundtruth, tum.read_trajectory(run_dir / "trajectory.tum")
    )
    assert len(ours) == engine["rpe_pairs"]
    assert pairs.rmse(ours.rpe_trans_mm) == pytest.approx(engine["rpe_trans_rmse_mm"], rel=1e-3)
    assert pairs.rmse(ours.rpe_rot_deg) == pytest.approx(engine["rpe_rot_rmse_deg"], rel=1e-3)
    assert "| fr1_desk_9frames | 1 |" in (out / "report.md").read_text()
