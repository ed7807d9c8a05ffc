"""Cross-check of the C++ `tum-score` CLI (slam_metrics) against evo 1.38.1's Python API.

For several trajectory pairs - the shipped RGBD-SLAM fr1/xyz estimate, seeded perturbations of
the ground truth (noise, drift, rigid offset, stamp jitter) and, when ../shared/data is present,
the other reference trajectories - both compute ATE (SE(3) Umeyama alignment, 20 ms association)
and frame-to-frame RPE, and the numbers must agree to 1e-7 m / 1e-6 deg.
The binary is looked up in $RGBD_BIN_DIR, else <repo>/build/bin (built by `make build`).
"""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

evo_sync = pytest.importorskip("evo.core.sync")
from evo.core import metrics  # noqa: E402
from evo.tools import file_interface  # noqa: E402

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
TESTDATA = HERE.parent / "testdata"
GT = TESTDATA / "fr1_xyz_groundtruth.txt"
MAX_DT_S = 0.02  # TUM benchmark association rule
TOL_M = 1e-7  # C++ prints 10 significant digits; definitions must agree far below 0.1 mm
TOL_DEG = 1e-6


def tum_score_binary() -> Path:
    bin_dir = Path(os.environ.get("RGBD_BIN_DIR", REPO / "build" / "bin"))
    exe = bin_dir / "tum-score"
    if not exe.exists():
        pytest.skip(f"{exe} not built (run `make build` or set RGBD_BIN_DIR)")
    return exe


def evo_numbers(gt_path: Path, est_path: Path) -> dict:
    gt = file_interface.read_tum_trajectory_file(str(gt_path))
    est = file_interface.read_tum_trajectory_file(str(est_path))
    ref, est_sync = evo_sync.associate_trajectories(gt, est, max_diff=MAX_DT_S)
    out = {}
    for rel, key in [
        (metrics.PoseRelation.translation_part, "rpe_trans"),
        (metrics.PoseRelation.rotation_angle_deg, "rpe_rot"),
    ]:
        rpe = metrics.RPE(rel, delta=1, delta_unit=metrics.Unit.frames, all_pairs=False)
        rpe.process_data((ref, est_sync))
        out[key + "_rmse"] = rpe.get_statistic(metrics.StatisticsType.rmse)
        out[key + "_mean"] = rpe.get_statistic(metrics.StatisticsType.mean)
        out["rpe_pairs"] = len(rpe.error)
    est_sync.align(ref, correct_scale=False)
    for rel, key in [
        (metrics.PoseRelation.translation_part, "ate"),
        (metrics.PoseRelation.rotation_angle_deg, "ate_rot"),
    ]:
        ape = metrics.APE(rel)
        ape.process_data((ref, est_sync))
        for stat in ("rmse", "mean", "median", "max"):
            out[f"{key}_{stat}"] = ape.get_statistic(metrics.StatisticsType[stat])
        out["pairs"] = len(ape.error)
    return out


def cpp_numbers(gt_path: Path, est_path: Path) -> dict:
    proc = subprocess.run(
        [str(tum_score_binary()), str(gt_path), str(est_path)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def assert_agree(gt_path: Path, est_path: Path) -> dict:
    cpp = cpp_numbers(gt_path, est_path)
    evo = evo_numbers(gt_path, est_path)
    assert cpp["pairs"] == evo["pairs"]
    assert cpp["rpe_pairs"] == evo["rpe_pairs"]
    for stat in ("rmse", "mean", "median", "max"):
        assert cpp[f"ate_{stat}_m"] == pytest.approx(evo[f"ate_{stat}"], abs=TOL_M), stat
    assert cpp["ate_rot_rmse_deg"] == pytest.approx(evo["ate_rot_rmse"], abs=TOL_DEG)
    assert cpp["rpe_trans_rmse_mm"] == pytest.approx(evo["rpe_trans_rmse"] * 1e3, abs=TOL_M * 1e3)
    assert cpp["rpe_trans_mean_mm"] == pytest.approx(evo["rpe_trans_mean"] * 1e3, abs=TOL_M * 1e3)
    assert cpp["rpe_rot_rmse_deg"] == pytest.approx(evo["rpe_rot_rmse"], abs=TOL_DEG)
    assert cpp["rpe_rot_mean_deg"] == pytest.approx(evo["rpe_rot_mean"], abs=TOL_DEG)
    return cpp


# ---- seeded perturbations of the ground truth -------------------------------------------------


def load_tum(path: Path) -> np.ndarray:
    return np.loadtxt(path, comments="#")


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (x, y, z, w) quaternions, row-wise."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=1,
    )


def small_rotation_quats(rng: np.random.Generator, n: int, sigma_rad: float) -> np.ndarray:
    rotvec = rng.normal(0.0, sigma_rad, size=(n, 3))
    angle = np.linalg.norm(rotvec, axis=1, keepdims=True)
    axis = np.divide(rotvec, angle, out=np.zeros_like(rotvec), where=angle > 0)
    return np.hstack([axis * np.sin(angle / 2), np.cos(angle / 2)])


def perturbed(kind: str, seed: int) -> np.ndarray:
    """A 30 Hz 'estimate' made from the 100 Hz ground truth; rows stamp tx ty tz qx qy qz qw."""
    rng = np.random.default_rng(seed)
    gt = load_tum(GT)
    est = gt[::3][:400].copy()  # ~30 Hz, 12 s
    n = len(est)
    if kind == "noise":
        est[:, 1:4] += rng.normal(0.0, 0.01, size=(n, 3))
        est[:, 4:8] = quat_mul(est[:, 4:8], small_rotation_quats(rng, n, 0.01))
    elif kind == "drift":
        est[:, 1:4] += np.cumsum(rng.normal(0.0, 0.002, size=(n, 3)), axis=0)
        est[:, 4:8] = quat_mul(est[:, 4:8], small_rotation_quats(rng, n, 0.003))
    elif kind == "rigid_offset_and_jitter":
        # A different world frame (rotation about z + shift) and +-8 ms stamp jitter.
        yaw = rng.uniform(-np.pi, np.pi)
        c, s = np.cos(yaw), np.sin(yaw)
        rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        est[:, 1:4] = est[:, 1:4] @ rot.T + rng.normal(0, 1.0, size=3)
        qz = np.tile([0, 0, np.sin(yaw / 2), np.cos(yaw / 2)], (n, 1))
        est[:, 4:8] = quat_mul(qz, est[:, 4:8])
        est[:, 1:4] += rng.normal(0.0, 0.005, size=(n, 3))
        est[:, 0] += rng.uniform(-0.008, 0.008, size=n)
        est = est[np.argsort(est[:, 0])]
    else:
        raise ValueError(kind)
    return est


@pytest.mark.parametrize(
    "est_name,expected_ate_m",
    [
        ("fr1_xyz_rgbdslam.txt", 0.0135),  # issue: 0.0135 m on the full sequence
        ("fr1_xyz_rgbdslam_first300.txt", 0.0148),  # issue: 0.0148 m on the first 300 frames
    ],
)
def test_shipped_reference_matches_evo_and_issue(est_name, expected_ate_m):
    cpp = assert_agree(GT, TESTDATA / est_name)
    assert cpp["ate_rmse_m"] == pytest.approx(expected_ate_m, abs=5e-5)


@pytest.mark.parametrize("kind", ["noise", "drift", "rigid_offset_and_jitter"])
@pytest.mark.parametrize("seed", [1, 2])
def test_perturbed_ground_truth_matches_evo(tmp_path, kind, seed):
    est_path = tmp_path / f"{kind}_{seed}.txt"
    np.savetxt(est_path, perturbed(kind, seed), fmt="%.9f", header="timestamp tx ty tz qx qy qz qw")
    cpp = assert_agree(GT, est_path)
    assert cpp["pairs"] == 400
    assert cpp["ate_rmse_m"] > 1e-4  # the perturbation is visible, not aligned away


SHARED = Path(os.environ.get("RGBD_DATA_DIR", REPO.parent / "shared" / "data"))
SHARED_PAIRS = [
    ("fr1_xyz_first300/groundtruth.txt", "reference_trajectories/freiburg1_xyz-rgbdslam_drift.txt"),
    ("fr2_desk_first50/groundtruth.txt", "reference_trajectories/fr2_desk_ORB.txt"),
]


@pytest.mark.parametrize("gt_rel,est_rel", SHARED_PAIRS)
def test_shared_reference_trajectories_match_evo(gt_rel, est_rel):
    gt_path, est_path = SHARED / gt_rel, SHARED / est_rel
    if not (gt_path.exists() and est_path.exists()):
        pytest.skip(f"shared data not at {SHARED} (set RGBD_DATA_DIR)")
    assert_agree(gt_path, est_path)


def test_bad_input_gives_message_and_nonzero_exit(tmp_path):
    broken = tmp_path / "broken.txt"
    broken.write_text("1 0 0 0 0 0 0 1\n2 0 zero 0 0 0 0 1\n")
    proc = subprocess.run(
        [str(tum_score_binary()), str(GT), str(broken)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 1
    assert "broken.txt:2: field 3 'zero' is not a finite number" in proc.stderr
    proc = subprocess.run(
        [str(tum_score_binary()), "--max-dt", "-1", str(GT), str(GT)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 2
    assert "--max-dt must be a positive number" in proc.stderr


def tum_associate(first: list, second: list, max_difference: float) -> list:
    """TUM's associate.py (rgbd_benchmark_tools), reimplemented: greedy by |dt|, unique stamps."""
    candidates = sorted(
        (abs(a - b), a, b) for a in first for b in second if abs(a - b) < max_difference
    )
    first_left, second_left, matches = set(first), set(second), []
    for _, a, b in candidates:
        if a in first_left and b in second_left:
            first_left.remove(a)
            second_left.remove(b)
            matches.append((a, b))
    return sorted(matches)


def test_tum_association_mode_matches_associate_py(tmp_path):
    # GIVEN an estimate as dense as the ground truth with +-12 ms stamp jitter, where evo's
    # nearest-stamp rule re-uses ground-truth stamps and associate.py's greedy rule does not.
    rng = np.random.default_rng(7)
    gt = load_tum(GT)[:600]
    est = gt.copy()
    est[:, 0] += rng.uniform(-0.012, 0.012, size=len(est))
    est[:, 1:4] += rng.normal(0.0, 0.005, size=(len(est), 3))
    est = est[np.argsort(est[:, 0])]
    est_path = tmp_path / "dense.txt"
    np.savetxt(est_path, est, fmt="%.9f")
    expected_pairs = tum_associate(list(gt[:, 0]), list(est[:, 0]), MAX_DT_S)
    proc = subprocess.run(
        [str(tum_score_binary()), "--association", "tum", str(GT), str(est_path)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    tum = json.loads(proc.stdout)
    evo_mode = cpp_numbers(GT, est_path)
    # THEN the tum mode finds exactly associate.py's pairs, and the two rules really differ here.
    assert tum["pairs"] == len(expected_pairs)
    assert tum["association"] == "tum_greedy"
    assert evo_mode["pairs"] != tum["pairs"]
    # ATE over associate.py's pairs with Horn's closed form (numpy), as evaluate_ate.py does.
    gt_by_stamp = {row[0]: row for row in load_tum(GT)}
    est_by_stamp = {row[0]: row for row in est}
    P = np.array([est_by_stamp[b][1:4] for a, b in expected_pairs]).T
    Q = np.array([gt_by_stamp[a][1:4] for a, b in expected_pairs]).T
    mu_p, mu_q = P.mean(axis=1, keepdims=True), Q.mean(axis=1, keepdims=True)
    U, _, Vt = np.linalg.svd((Q - mu_q) @ (P - mu_p).T)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ S @ Vt
    residual = Q - (R @ (P - mu_p) + mu_q)
    ate = np.sqrt(np.mean(np.sum(residual**2, axis=0)))
    assert tum["ate_rmse_m"] == pytest.approx(ate, abs=TOL_M)
