"""rolling_shutter_check.py: a known readout is measured back, and bad input is refused."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import rolling_shutter_check as rsc  # noqa: E402
from slam_study import se3, tum  # noqa: E402

kMocapPeriodS = 0.01  # the TUM motion capture's 100 Hz
kFramePeriodS = 1 / 30


def _rotvec(t: np.ndarray) -> np.ndarray:
    """A hand-held-like turn: each axis oscillating, not in phase (peak rates ~0.5-1 rad/s)."""
    return np.stack([0.3 * np.sin(1.7 * t + 1.0), 0.4 * np.sin(2.1 * t), 0.2 * np.cos(2.9 * t)], 1)


def _write_gt(path: Path, span_s: float) -> tum.Trajectory:
    t = np.arange(0.0, span_s, kMocapPeriodS) + 1000.0
    rv = _rotvec(t - 1000.0)
    angle = np.linalg.norm(rv, axis=1, keepdims=True)
    q = np.concatenate([rv / np.maximum(angle, 1e-12) * np.sin(angle / 2), np.cos(angle / 2)], 1)
    traj = tum.Trajectory(t, se3.make_poses(np.zeros((len(t), 3)), q))
    tum.write_trajectory(path, traj)
    return traj


def _write_frames(path: Path, stamps: np.ndarray, rates: list[list[float] | None]) -> None:
    lines = [
        "index,stamp_s,state,rolling_shutter_rate_x,rolling_shutter_rate_y,rolling_shutter_rate_z"
    ]
    for i, (s, r) in enumerate(zip(stamps, rates, strict=True)):
        cells = ",".join(f"{v:.6f}" for v in r) if r is not None else ",,"
        lines.append(f"{i},{s:.6f},tracking,{cells}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_given_rows_rates_of_a_known_readout_then_it_is_measured_back(tmp_path):
    # GIVEN a camera with a 24 ms readout tracked by a run that assumed 30 ms: its rows' rate is
    # the true rate x 24/30, with noise; some frames have no rate (untracked)
    gt = _write_gt(tmp_path / "gt.txt", 10.0)
    stamps = np.arange(0.5, 9.5, kFramePeriodS) + 1000.0
    true_rate, ok = rsc.mocap_rates(gt, stamps)
    assert ok.all()
    rng = np.random.default_rng(3)
    rows = true_rate * (0.024 / 0.030) + rng.normal(0.0, 0.05, true_rate.shape)
    rates = [list(r) if i % 10 else None for i, r in enumerate(rows)]
    _write_frames(tmp_path / "frames.csv", stamps, rates)
    # WHEN checked
    e = rsc.check(str(tmp_path / "gt.txt"), str(tmp_path / "frames.csv"), 0.030)
    # THEN the readout is the true one, from the frames that had a rate
    assert e.frames == len(stamps) - len(stamps[::10])
    assert e.readout_s == pytest.approx(0.024, abs=0.0005)
    assert all(c > 0.9 for c in e.correlation)
    assert "readout 24." in rsc.format_estimate(e)


def test_the_mocap_rate_is_the_camera_frame_turn_over_the_frame_interval(tmp_path):
    # GIVEN a camera turning about its own y axis at a constant 0.5 rad/s
    t = np.arange(0.0, 2.0, kMocapPeriodS) + 50.0
    q = np.stack([0 * t, np.sin(0.25 * (t - 50)), 0 * t, np.cos(0.25 * (t - 50))], 1)
    gt = tum.Trajectory(t, se3.make_poses(np.zeros((len(t), 3)), q))
    # WHEN its rate is read at a frame's stamp
    rate, ok = rsc.mocap_rates(gt, np.array([51.0]))
    # THEN it is (0, 0.5, 0) rad/s
    assert ok[0]
    np.testing.assert_allclose(rate[0], [0.0, 0.5, 0.0], atol=1e-9)


def test_bad_input_is_refused_with_a_reason(tmp_path, capsys):
    gt = _write_gt(tmp_path / "gt.txt", 3.0)
    stamps = np.arange(0.5, 2.5, kFramePeriodS) + 1000.0
    # frames.csv of a run without the rate columns
    (tmp_path / "old.csv").write_text("index,stamp_s\n0,1000.5\n", encoding="utf-8")
    with pytest.raises(ValueError, match="rolling_shutter_rate_x"):
        rsc.check(str(tmp_path / "gt.txt"), str(tmp_path / "old.csv"), 0.03)
    # a run that assumed no rolling shutter
    _write_frames(tmp_path / "frames.csv", stamps, [[0.0, 0.0, 0.0]] * len(stamps))
    with pytest.raises(ValueError, match="readout > 0"):
        rsc.check(str(tmp_path / "gt.txt"), str(tmp_path / "frames.csv"), 0.0)
    # too few frames with a rate
    _write_frames(tmp_path / "few.csv", stamps[:3], [[0.1, 0.1, 0.1]] * 3)
    with pytest.raises(ValueError, match="only 3 frame"):
        rsc.check(str(tmp_path / "gt.txt"), str(tmp_path / "few.csv"), 0.03)
    # a camera that does not turn
    still = tum.Trajectory(
        gt.stamps_s, se3.make_poses(np.zeros((len(gt), 3)), np.tile([0, 0, 0, 1.0], (len(gt), 1)))
    )
    tum.write_trajectory(tmp_path / "still.txt", still)
    with pytest.raises(ValueError, match="hardly turns"):
        rsc.check(str(tmp_path / "still.txt"), str(tmp_path / "frames.csv"), 0.03)
    # the command line: no metrics.json beside frames.csv and no --readout-s
    assert (
        rsc.main(["--gt", str(tmp_path / "gt.txt"), "--frames", str(tmp_path / "frames.csv")]) == 1
    )
    assert "rolling_shutter_check:" in capsys.readouterr().err
