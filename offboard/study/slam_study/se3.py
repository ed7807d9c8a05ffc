"""Rigid-body helpers on 4x4 homogeneous matrices (numpy, vectorised over a leading axis).

Conventions: quaternions are Hamilton, stored in TUM order (qx, qy, qz, qw); a pose `T_world_cam`
maps camera-frame points to the world frame. Angles returned in degrees carry `_deg` in the name.
"""

from __future__ import annotations

import numpy as np

# Below this rotation angle (rad) the log map uses its first-order series: sin(a)/a is 1 to double
# precision there, and the exact formula would divide by ~0.
kSmallAngleRad = 1e-9


def quat_xyzw_to_rot(q_xyzw: np.ndarray) -> np.ndarray:
    """(N,4) or (4,) unit quaternions (qx,qy,qz,qw) -> (N,3,3) or (3,3) rotation matrices.

    Quaternions are normalised first (TUM files print 4 decimals, so norms drift by ~1e-4).
    Raises ValueError on a zero or non-finite quaternion.
    """
    q = np.asarray(q_xyzw, dtype=float)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    norms = np.linalg.norm(q, axis=1)
    if not np.all(np.isfinite(q)) or np.any(norms < 1e-12):
        raise ValueError("quaternion is zero or not finite")
    x, y, z, w = (q / norms[:, None]).T
    rot = np.empty((q.shape[0], 3, 3))
    rot[:, 0, 0] = 1 - 2 * (y * y + z * z)
    rot[:, 0, 1] = 2 * (x * y - z * w)
    rot[:, 0, 2] = 2 * (x * z + y * w)
    rot[:, 1, 0] = 2 * (x * y + z * w)
    rot[:, 1, 1] = 1 - 2 * (x * x + z * z)
    rot[:, 1, 2] = 2 * (y * z - x * w)
    rot[:, 2, 0] = 2 * (x * z - y * w)
    rot[:, 2, 1] = 2 * (y * z + x * w)
    rot[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return rot[0] if single else rot


def rot_to_quat_xyzw(rot: np.ndarray) -> np.ndarray:
    """(3,3) rotation matrix -> unit quaternion (qx,qy,qz,qw) with qw >= 0."""
    m = np.asarray(rot, dtype=float)
    tr = np.trace(m)
    if tr > 0:
        s = np.sqrt(tr + 1.0) * 2
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def make_poses(translation_m: np.ndarray, q_xyzw: np.ndarray) -> np.ndarray:
    """(N,3) translations in metres + (N,4) quaternions -> (N,4,4) homogeneous poses."""
    t = np.atleast_2d(np.asarray(translation_m, dtype=float))
    poses = np.tile(np.eye(4), (t.shape[0], 1, 1))
    poses[:, :3, :3] = quat_xyzw_to_rot(np.atleast_2d(q_xyzw))
    poses[:, :3, 3] = t
    return poses


def inverse(poses: np.ndarray) -> np.ndarray:
    """Inverse of (N,4,4) or (4,4) rigid transforms, using R^T (exact for rotations)."""
    p = np.asarray(poses, dtype=float)
    rot_t = np.swapaxes(p[..., :3, :3], -1, -2)
    out = np.zeros_like(p)
    out[..., :3, :3] = rot_t
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", rot_t, p[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def relative(poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
    """A^-1 B for matching stacks: the motion from frame a to frame b, expressed in frame a."""
    return inverse(poses_a) @ np.asarray(poses_b, dtype=float)


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """Log map: (N,3,3) rotations -> (N,3) axis*angle in radians (angle in [0, pi])."""
    r = np.asarray(rot, dtype=float)
    single = r.ndim == 2
    r = r.reshape(-1, 3, 3)
    cos_a = np.clip((np.trace(r, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos_a)
    skew = np.stack(
        [r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], axis=1
    )
    out = np.empty((r.shape[0], 3))
    small = angle < kSmallAngleRad
    out[small] = 0.5 * skew[small]
    big = ~small
    sin_a = np.sin(angle[big])
    near_pi = sin_a < 1e-6
    regular = np.where(big)[0][~near_pi]
    out[regular] = skew[regular] * (angle[regular] / (2.0 * np.sin(angle[regular])))[:, None]
    for idx in np.where(big)[0][near_pi]:
        # angle ~ pi: axis from the diagonal of (R + I) / 2 = a a^T.
        aat = (r[idx] + np.eye(3)) / 2.0
        col = int(np.argmax(np.diag(aat)))
        axis = aat[:, col] / np.sqrt(max(aat[col, col], 1e-300))
        out[idx] = axis * angle[idx]
    return out[0] if single else out


def rotation_angle_deg(rot: np.ndarray) -> np.ndarray:
    """Rotation angle in degrees of (N,3,3) or (3,3) rotation matrices."""
    r = np.asarray(rot, dtype=float)
    cos_a = np.clip((np.trace(r, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    return np.degrees(np.arccos(cos_a))


def align_rigid(model_m: np.ndarray, data_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horn/Umeyama least-squares rigid alignment (no scale): R, t minimising |R data + t - model|.

    model_m, data_m: (N,3) corresponding positions in metres, N >= 3 for a unique rotation.
    """
    mu_m = model_m.mean(axis=0)
    mu_d = data_m.mean(axis=0)
    cov = (model_m - mu_m).T @ (data_m - mu_d) / model_m.shape[0]
    u, _, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1.0
    rot = u @ s @ vt
    return rot, mu_m - rot @ mu_d
