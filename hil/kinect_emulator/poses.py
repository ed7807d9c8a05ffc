"""Pose helpers: the camera pose in the room from the flight-controller emulator's NED state.

Room frame: x north, y west, z up (right-handed; "NWU"), origin on the floor at the take-off point
plus
`origin_room_m`. Camera optical frame: x right, y down, z forward. The Kinect is mounted looking
along the body's x axis (forward), pitched down by mount_pitch_down_deg.
T_room_cam (4x4) maps camera points to room points.
"""

from __future__ import annotations

import math

import numpy as np
from fc_emulator.quad_model import rotation_body_to_ned

# NED -> NWU: flip y and z.
R_NWU_NED = np.diag([1.0, -1.0, -1.0])


def pose_matrix(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, dtype=float)
    return T


def r_body_cam(mount_pitch_down_deg: float) -> np.ndarray:
    """Rotation taking camera-optical vectors to body FRD vectors."""
    # Level camera: cam z (forward) = body x, cam x (right) = body y, cam y (down) = body z.
    base = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    a = math.radians(mount_pitch_down_deg)
    # Pitch down about body y by a: forward axis tips towards body +z (down).
    pitch = np.array(
        [[math.cos(a), 0.0, -math.sin(a)], [0.0, 1.0, 0.0], [math.sin(a), 0.0, math.cos(a)]]
    )
    return pitch @ base


def camera_pose_from_ned(
    pos_ned_m,
    roll_rad: float,
    pitch_rad: float,
    yaw_rad: float,
    mount_pitch_down_deg: float = 30.0,
    cam_offset_body_m=(0.1, 0.0, 0.05),
    origin_room_m=(0.0, 0.0, 0.0),
) -> np.ndarray:
    """T_room_cam for a craft at pos_ned_m (relative to take-off) with the given attitude.

    cam_offset_body_m: camera optical centre in body FRD (m): 10 cm forward, 5 cm below the centre.
    Default mount 30 deg down: the floor fills the lower part of the view at hover (see
    offboard/quadcontrol/map/floor_plane.hpp, which expects an angled mount).
    """
    R_ned_body = rotation_body_to_ned(roll_rad, pitch_rad, yaw_rad)
    p_ned = np.asarray(pos_ned_m, dtype=float) + R_ned_body @ np.asarray(
        cam_offset_body_m, dtype=float
    )
    R_room_cam = R_NWU_NED @ R_ned_body @ r_body_cam(mount_pitch_down_deg)
    return pose_matrix(R_room_cam, R_NWU_NED @ p_ned + np.asarray(origin_room_m, dtype=float))


def rotation_to_quaternion_xyzw(R: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w order, as in TUM groundtruth files) of a rotation matrix."""
    m = R
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w, x, y, z = (
            0.25 * s,
            (m[2, 1] - m[1, 2]) / s,
            (m[0, 2] - m[2, 0]) / s,
            (m[1, 0] - m[0, 1]) / s,
        )
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        w, x, y, z = (
            (m[2, 1] - m[1, 2]) / s,
            0.25 * s,
            (m[0, 1] + m[1, 0]) / s,
            (m[0, 2] + m[2, 0]) / s,
        )
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        w, x, y, z = (
            (m[0, 2] - m[2, 0]) / s,
            (m[0, 1] + m[1, 0]) / s,
            0.25 * s,
            (m[1, 2] + m[2, 1]) / s,
        )
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        w, x, y, z = (
            (m[1, 0] - m[0, 1]) / s,
            (m[0, 2] + m[2, 0]) / s,
            (m[1, 2] + m[2, 1]) / s,
            0.25 * s,
        )
    q = np.array([x, y, z, w])
    q /= np.linalg.norm(q)
    if q[3] < 0:
        q = -q
    return tuple(float(v) for v in q)
