"""Per-pair RPE, axis shares, ATE: exact cases by construction, and evo as the reference."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from slam_study import pairs, se3, tum


def _straight_line(n: int, step_m: np.ndarray, dt_s: float = 1 / 30) -> tum.Trajectory:
    stamps = 100.0 + dt_s * np.arange(n)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, 3] = np.outer(np.arange(n), step_m)
    return tum.Trajectory(stamps, poses)


def _rot_z(angle_deg: float) -> np.ndarray:
    a = np.radians(angle_deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_given_identical_trajectories_when_paired_then_error_is_zero():
    gt = _straight_line(10, np.array([0.005, 0, 0]))
    p = pairs.motion_pairs(gt, gt)
    assert len(p) == 9
    np.testing.assert_allclose(p.rpe_trans_mm, 0, atol=1e-9)
    np.testing.assert_allclose(p.rpe_rot_deg, 0, atol=1e-6)
    np.testing.assert_allclose(p.gt_trans_mm, 5.0)
    np.testing.assert_allclose(p.trans_share[:, 0], 1.0)


def test_given_estimate_overshooting_each_step_when_paired_then_rpe_is_the_overshoot():
    gt = _straight_line(6, np.array([0, 0, 0.010]))  # 10 mm along the optical axis
    est = _straight_line(6, np.array([0, 0, 0.013]))  # 13 mm per step
    p = pairs.motion_pairs(gt, est)
    np.testing.assert_allclose(p.rpe_trans_mm, 3.0, atol=1e-9)
    np.testing.assert_allclose(p.trans_share[:, 2], 1.0)  # z share


@pytest.mark.parametrize("axis_index, expected_axis", [(2, "roll"), (0, "pitch"), (1, "yaw")])
def test_given_rotation_about_one_camera_axis_then_its_share_is_one(axis_index, expected_axis):
    gt = _straight_line(4, np.zeros(3))
    rotvec = np.zeros(3)
    rotvec[axis_index] = np.radians(1.0)
    angle = np.linalg.norm(rotvec)
    q = np.append(np.sin(angle / 2) * rotvec / angle, np.cos(angle / 2))
    step = se3.quat_xyzw_to_rot(q)
    for i in range(len(gt)):
        gt.poses[i, :3, :3] = np.linalg.matrix_power(step, i)
    p = pairs.motion_pairs(gt, gt)
    np.testing.assert_allclose(p.gt_rot_deg, 1.0, atol=1e-9)
    np.testing.assert_allclose(p.rot_share[:, pairs.kRotAxes.index(expected_axis)], 1.0)


def test_given_motion_then_shares_are_in_the_first_frames_camera_frame():
    # GIVEN a camera yawed 90 deg in the world, moving along world y
    gt = _straight_line(3, np.array([0, 0.01, 0]))
    gt.poses[:, :3, :3] = _rot_z(90.0)
    p = pairs.motion_pairs(gt, gt)
    # THEN in its own frame that is its x axis (world y = camera x after a 90 deg turn about z)
    np.testing.assert_allclose(p.trans_share[:, 0], 1.0, atol=1e-12)


def test_given_estimate_frame_without_ground_truth_then_pairs_around_it_are_dropped():
    gt = _straight_line(10, np.array([0.005, 0, 0]))
    gt_missing = gt.subset(np.array([0, 1, 2, 3, 5, 6, 7, 8, 9]))  # no ground truth at frame 4
    p = pairs.motion_pairs(gt_missing, gt)
    assert len(p) == 7  # pairs (3,4) and (4,5) dropped, not bridged into a 10 mm pair
    np.testing.assert_allclose(p.gt_trans_mm, 5.0)


def test_ate_of_a_rigidly_moved_copy_is_zero():
    gt = _straight_line(20, np.array([0.01, 0.004, 0.002]))
    gt.poses[:, 0, 3] += 0.1 * np.sin(np.arange(20))
    moved = copy.deepcopy(gt)
    tf = np.eye(4)
    tf[:3, :3] = _rot_z(30.0)
    tf[:3, 3] = [1, 2, 3]
    moved = tum.Trajectory(gt.stamps_s, tf @ gt.poses)
    ate = pairs.absolute_trajectory_error(gt, moved)
    assert ate.rmse_m == pytest.approx(0.0, abs=1e-9)
    assert pairs.absolute_trajectory_error(gt.subset([0, 1]), moved) is None


def test_rotation_vector_round_trip_including_near_pi():
    rng = np.random.default_rng(7)
    vecs = rng.normal(size=(50, 3))
    vecs *= (rng.uniform(0, np.pi - 1e-3, 50) / np.linalg.norm(vecs, axis=1))[:, None]
    vecs[0] = [0, 0, np.pi - 1e-8]
    angles = np.linalg.norm(vecs, axis=1)
    quats = np.hstack(
        [np.sin(angles / 2)[:, None] * vecs / angles[:, None], np.cos(angles / 2)[:, None]]
    )
    back = se3.rotation_vector(se3.quat_xyzw_to_rot(quats))
    np.testing.assert_allclose(np.abs(back[0]), np.abs(vecs[0]), atol=1e-6)
    np.testing.assert_allclose(back[1:], vecs[1:], atol=1e-7)
    for q in quats[1:5]:
        np.testing.assert_allclose(
            np.abs(se3.rot_to_quat_xyzw(se3.quat_xyzw_to_rot(q))), np.abs(q), atol=1e-12
        )


def _noisy_estimate(gt: tum.Trajectory, seed: int) -> tum.Trajectory:
    rng = np.random.default_rng(seed)
    poses = gt.poses.copy()
    poses[:, :3, 3] += rng.normal(0, 0.004, (len(gt), 3))
    for i in range(len(gt)):
        angle = np.radians(rng.normal(0, 0.3, 3))
        poses[i, :3, :3] = poses[i, :3, :3] @ se3.quat_xyzw_to_rot(
            np.append(np.sin(angle / 2), 1.0)
        )
    return tum.Trajectory(gt.stamps_s + 0.003, poses)


def test_rpe_and_ate_match_evo(fr1_xyz30, tmp_path):
    """GIVEN real ground truth at the colour frames of fr1/xyz (first 30) and a seeded noisy
    estimate, WHEN both we and evo 1.38.1 score it, THEN RPE RMSE (delta 1 frame) and ATE agree."""
    from evo.core import metrics as evo_metrics
    from evo.core import sync
    from evo.tools import file_interface

    ds = tum.Dataset.load(fr1_xyz30)
    gt = ds.groundtruth_at_frames(1)
    est = _noisy_estimate(gt, seed=42)
    est_file = tmp_path / "est.tum"
    tum.write_trajectory(est_file, est)
    ours = pairs.motion_pairs(ds.groundtruth, tum.read_trajectory(est_file))
    ours_ate = pairs.absolute_trajectory_error(ds.groundtruth, tum.read_trajectory(est_file))

    traj_gt = file_interface.read_tum_trajectory_file(str(fr1_xyz30 / "groundtruth.txt"))
    traj_est = file_interface.read_tum_trajectory_file(str(est_file))
    traj_gt, traj_est = sync.associate_trajectories(traj_gt, traj_est, max_diff=0.02)
    rpe_t = evo_metrics.RPE(
        evo_metrics.PoseRelation.translation_part, delta=1, delta_unit=evo_metrics.Unit.frames
    )
    rpe_t.process_data((traj_gt, traj_est))
    rpe_r = evo_metrics.RPE(
        evo_metrics.PoseRelation.rotation_angle_deg, delta=1, delta_unit=evo_metrics.Unit.frames
    )
    rpe_r.process_data((traj_gt, traj_est))
    aligned = copy.deepcopy(traj_est)
    aligned.align(traj_gt)
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((traj_gt, aligned))

    assert len(ours) == len(rpe_t.error) == 29
    assert pairs.rmse(ours.rpe_trans_mm) == pytest.approx(
        1000 * rpe_t.get_statistic(evo_metrics.StatisticsType.rmse), rel=1e-6
    )
    assert pairs.rmse(ours.rpe_rot_deg) == pytest.approx(
        rpe_r.get_statistic(evo_metrics.StatisticsType.rmse), rel=1e-5
    )
    assert ours_ate.rmse_m == pytest.approx(
        ape.get_statistic(evo_metrics.StatisticsType.rmse), rel=1e-6
    )


def test_effect_fit_recovers_known_coefficients():
    """GIVEN pairs whose error is exactly 1 + 0.4 t + 4 r + 0.1 t r (+ small seeded noise)
    THEN the least-squares fit in the thesis comparison recovers the coefficients."""
    from slam_study import report
    from slam_study.tests.test_tables import make_pairs

    rng = np.random.default_rng(3)
    t = rng.uniform(0, 18, 400)
    r = rng.uniform(0, 1.8, 400)
    err = 1 + 0.4 * t + 4 * r + 0.1 * t * r + rng.normal(0, 0.01, 400)
    coef, se = report.effect_fit(make_pairs(t, r, rpe_mm=err))
    np.testing.assert_allclose(coef, [1, 0.4, 4, 0.1], atol=0.02)
    assert np.all(se < 0.02)
    assert report.effect_fit(make_pairs(t[:5], r[:5], rpe_mm=err[:5])) is None
    additive, _ = report.effect_fit(make_pairs(t, r, rpe_mm=1 + 0.4 * t + 4 * r), interaction=False)
    np.testing.assert_allclose(additive, [1, 0.4, 4], atol=1e-9)
