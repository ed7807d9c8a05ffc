"""stamp_lag.py: a known lag of orientation or position is found, and bad input is refused."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import stamp_lag  # noqa: E402
from slam_study import se3, tum  # noqa: E402

kMocapPeriodS = 0.01  # the TUM motion capture's 100 Hz
kFramePeriodS = 1 / 30


def _motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A hand-held-like motion: position and rotation vector, both oscillating, not in phase."""
    pos = np.stack([0.2 * np.sin(1.3 * t), 0.1 * np.sin(2.1 * t + 0.5), 0.15 * np.cos(0.9 * t)], 1)
    rotvec = np.stack(
        [0.2 * np.sin(1.7 * t + 1.0), 0.25 * np.sin(1.1 * t), 0.1 * np.cos(2.3 * t)], 1
    )
    return pos, rotvec


def _poses(pos: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    angle = np.linalg.norm(rotvec, axis=1, keepdims=True)
    axis = rotvec / np.maximum(angle, 1e-12)
    q = np.concatenate([axis * np.sin(angle / 2), np.cos(angle / 2)], axis=1)
    return se3.make_poses(pos, q)


def _trajectories(
    orientation_lag_s: float,
    position_lag_s: float,
    span_s: float = 8.0,
    hand_eye: np.ndarray | None = None,
):
    t_gt = np.arange(0.0, span_s, kMocapPeriodS)
    pos, rv = _motion(t_gt)
    gt = tum.Trajectory(t_gt, _poses(pos, rv))
    t_est = np.arange(0.5, span_s - 0.5, kFramePeriodS)
    pos_e, _ = _motion(t_est - position_lag_s)
    _, rv_e = _motion(t_est - orientation_lag_s)
    # The estimate lives in its own world frame: a rigid transform the alignment must undo.
    world = _poses(np.array([[1.0, -2.0, 0.5]]), np.array([[0.3, -0.2, 1.0]]))[0]
    est = world @ _poses(pos_e, rv_e)
    if hand_eye is not None:  # the estimate's camera is rotated against the motion-capture body
        est[:, :3, :3] = est[:, :3, :3] @ hand_eye
    return gt, tum.Trajectory(t_est, est)


def test_an_orientation_that_lags_while_the_position_does_not_is_told_apart():
    gt, est = _trajectories(orientation_lag_s=0.020, position_lag_s=0.0)
    report = stamp_lag.stamp_lag(gt, est, max_shift_s=0.05, step_s=0.005)
    assert report.best_orientation().shift_s == pytest.approx(-0.020, abs=1e-9)
    assert report.best_position().shift_s == pytest.approx(0.0, abs=1e-9)
    assert report.best_position().position_rmse_m < 1e-4
    assert report.best_orientation().orientation_rms_deg < 0.01


def test_a_constant_camera_side_rotation_is_not_counted_as_orientation_error():
    hand_eye = _poses(np.zeros((1, 3)), np.array([[0.03, -0.05, 0.02]]))[0, :3, :3]
    gt, est = _trajectories(orientation_lag_s=0.010, position_lag_s=0.0, hand_eye=hand_eye)
    report = stamp_lag.stamp_lag(gt, est, max_shift_s=0.05, step_s=0.005)
    assert report.best_orientation().shift_s == pytest.approx(-0.010, abs=1e-9)
    assert report.best_orientation().orientation_rms_deg < 0.01


def test_a_whole_pose_lag_moves_both_minima():
    gt, est = _trajectories(orientation_lag_s=0.030, position_lag_s=0.030)
    report = stamp_lag.stamp_lag(gt, est, max_shift_s=0.05, step_s=0.005)
    assert report.best_orientation().shift_s == pytest.approx(-0.030, abs=1e-9)
    assert report.best_position().shift_s == pytest.approx(-0.030, abs=1e-9)
    text = stamp_lag.format_report(report)
    assert "position best at -30.0 ms" in text and "orientation best at -30.0 ms" in text


def test_every_shift_scores_the_same_poses():
    gt, est = _trajectories(0.0, 0.0, span_s=2.0)
    report = stamp_lag.stamp_lag(gt, est, max_shift_s=0.6, step_s=0.2)
    # Estimate stamps run 0.5 ... 1.5 s: shifted by -0.6 s the first ones fall before the ground
    # truth.
    assert report.poses < len(est)
    assert [round(s.shift_s, 3) for s in report.scores] == [-0.6, -0.4, -0.2, 0.0, 0.2, 0.4, 0.6]


def test_an_estimate_outside_the_ground_truth_is_a_clear_error(tmp_path, capsys):
    gt, est = _trajectories(0.0, 0.0)
    later = tum.Trajectory(est.stamps_s + 100.0, est.poses)
    tum.write_trajectory(tmp_path / "gt.txt", gt)
    tum.write_trajectory(tmp_path / "est.txt", later)
    assert (
        stamp_lag.main(["--gt", str(tmp_path / "gt.txt"), "--est", str(tmp_path / "est.txt")]) == 1
    )
    assert "lie inside the ground truth" in capsys.readouterr().err


def test_a_ground_truth_dropout_is_not_interpolated_across():
    gt, est = _trajectories(0.0, 0.0)
    gap = (gt.stamps_s > 3.0) & (gt.stamps_s < 3.2)
    holed = gt.subset(np.where(~gap)[0])
    report = stamp_lag.stamp_lag(holed, est, max_shift_s=0.02, step_s=0.01)
    full = stamp_lag.stamp_lag(gt, est, max_shift_s=0.02, step_s=0.01)
    assert report.poses < full.poses


def test_a_malformed_file_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "gt.txt").write_text("1.0 0 0 0 0 0 0\n")
    (tmp_path / "est.txt").write_text("1.0 0 0 0 0 0 0 1\n")
    assert (
        stamp_lag.main(["--gt", str(tmp_path / "gt.txt"), "--est", str(tmp_path / "est.txt")]) == 1
    )
    assert "expected 8 fields" in capsys.readouterr().err
