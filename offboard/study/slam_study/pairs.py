"""Per-frame-pair classification and error: the raw material of Tables 4.14-4.21.

For consecutive associated frames i, i+1 of an estimate P (at whatever rate it was produced) and
ground truth Q:
    gt motion  M = Q_i^-1 Q_{i+1}        (expressed in the camera frame of frame i)
    error      E = M^-1 (P_i^-1 P_{i+1})  (the TUM/evo RPE with a one-frame delta)
translation in mm, rotation angle in degrees. The pair is binned by |M|.

Axis shares are measured in the camera (optical) frame of frame i: x right, y down, z forward
along the optical axis. Rotation axes are named as on the vehicle looking forward: roll about the
optical axis z, pitch about x, yaw about y. A share is the component's fraction of the L1 norm
(|t_x| / (|t_x|+|t_y|+|t_z|), likewise for the rotation vector), so shares add up to 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slam_study import se3
from slam_study.tum import Trajectory, associate, kMaxAssociationDiffS

kTransAxes = ("x", "y", "z")
kRotAxes = ("roll", "pitch", "yaw")
# Index into the optical-frame rotation vector (x, y, z) for roll, pitch, yaw.
kRotAxisIndex = {"roll": 2, "pitch": 0, "yaw": 1}


@dataclass(frozen=True)
class PairTable:
    """Column arrays, one row per consecutive pair. Lengths are equal."""

    stamp_s: np.ndarray  # time of frame i
    dt_s: np.ndarray  # time between the frames
    gt_trans_mm: np.ndarray  # |translation of M|
    gt_rot_deg: np.ndarray  # rotation angle of M
    trans_share: np.ndarray  # (n,3) x, y, z L1 shares of M's translation
    rot_share: np.ndarray  # (n,3) roll, pitch, yaw L1 shares of M's rotation vector
    rpe_trans_mm: np.ndarray  # |translation of E|
    rpe_rot_deg: np.ndarray  # rotation angle of E

    def __len__(self) -> int:
        return int(self.stamp_s.shape[0])

    @staticmethod
    def concat(tables: list[PairTable]) -> PairTable:
        if not tables:
            return empty_pairs()
        return PairTable(
            *(
                np.concatenate([getattr(t, f) for t in tables])
                for f in PairTable.__dataclass_fields__
            )
        )

    def select(self, mask: np.ndarray) -> PairTable:
        return PairTable(*(getattr(self, f)[mask] for f in PairTable.__dataclass_fields__))


def empty_pairs() -> PairTable:
    z = np.zeros(0)
    return PairTable(z, z, z, z, np.zeros((0, 3)), np.zeros((0, 3)), z, z)


def _l1_shares(vectors: np.ndarray) -> np.ndarray:
    mag = np.abs(vectors)
    total = mag.sum(axis=1, keepdims=True)
    return np.divide(mag, total, out=np.zeros_like(mag), where=total > 0)


def motion_pairs(
    gt: Trajectory, est: Trajectory, max_diff_s: float = kMaxAssociationDiffS
) -> PairTable:
    """Pairs of consecutive estimate poses that both have ground truth within max_diff_s.

    An estimate frame without ground truth breaks the chain: the pairs on either side of it are
    dropped rather than bridged (bridging would double the motion of that pair).
    """
    ie, ig = associate(est.stamps_s, gt.stamps_s, max_diff_s)
    if ie.size < 2:
        return empty_pairs()
    consecutive = np.diff(ie) == 1
    a = np.where(consecutive)[0]
    b = a + 1
    q_rel = se3.relative(gt.poses[ig[a]], gt.poses[ig[b]])
    p_rel = se3.relative(est.poses[ie[a]], est.poses[ie[b]])
    err = se3.inverse(q_rel) @ p_rel
    rot_vec = se3.rotation_vector(q_rel[:, :3, :3])
    rot_pyr = rot_vec[:, [kRotAxisIndex[a_] for a_ in kRotAxes]]
    return PairTable(
        stamp_s=est.stamps_s[ie[a]],
        dt_s=est.stamps_s[ie[b]] - est.stamps_s[ie[a]],
        gt_trans_mm=1000.0 * np.linalg.norm(q_rel[:, :3, 3], axis=1),
        gt_rot_deg=se3.rotation_angle_deg(q_rel[:, :3, :3]),
        trans_share=_l1_shares(q_rel[:, :3, 3]),
        rot_share=_l1_shares(rot_pyr),
        rpe_trans_mm=1000.0 * np.linalg.norm(err[:, :3, 3], axis=1),
        rpe_rot_deg=se3.rotation_angle_deg(err[:, :3, :3]),
    )


@dataclass(frozen=True)
class AteResult:
    rmse_m: float
    mean_m: float
    max_m: float
    n: int
    aligned_est: Trajectory  # the estimate moved into the ground-truth frame


def absolute_trajectory_error(
    gt: Trajectory, est: Trajectory, max_diff_s: float = kMaxAssociationDiffS
) -> AteResult | None:
    """ATE as the TUM tools define it: associate, rigid (no scale) Horn alignment of the estimate's
    positions onto ground truth, RMSE of position differences. None with fewer than 3 matches."""
    ie, ig = associate(est.stamps_s, gt.stamps_s, max_diff_s)
    if ie.size < 3:
        return None
    rot, trans = se3.align_rigid(gt.positions_m()[ig], est.positions_m()[ie])
    tf = np.eye(4)
    tf[:3, :3] = rot
    tf[:3, 3] = trans
    moved = tf @ est.poses
    diff = np.linalg.norm(moved[ie, :3, 3] - gt.positions_m()[ig], axis=1)
    return AteResult(
        float(np.sqrt(np.mean(diff**2))),
        float(diff.mean()),
        float(diff.max()),
        int(ie.size),
        Trajectory(est.stamps_s, moved),
    )


def rmse(values: np.ndarray) -> float:
    v = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")
