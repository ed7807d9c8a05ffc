"""Ground-truth pilot: a stand-in ground station that flies the FC emulator from its true state.

Used by rig self-checks (e.g. recording a flight for SLAM) where the real quad-control is not in the
loop; it reads the emulator's ground truth, never SLAM. It maps position error to ArduCopter stick
inputs the way a pilot in AltHold would: climb rate from altitude error, lean angle from horizontal
position/velocity error (a PD loop), yaw rate from heading error.
Pure function of (snapshot, target): no clock, no state besides the target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fc_emulator.emulator import (
    ANGLE_MAX_RAD,
    PILOT_SPEED_UP_MPS,
    STICK_DEADZONE_US,
    THR_DZ,
    YAW_RATE_MAX_RAD_S,
    FcSnapshot,
)
from fc_emulator.quad_model import GRAVITY_MSS, wrap_pi

ARM_STICKS_US = (
    1500,
    1500,
    1000,
    2000,
)  # throttle zero, yaw full right (ArduCopter arming gesture)
IDLE_STICKS_US = (1500, 1500, 1000, 1500)


@dataclass(frozen=True)
class PilotGains:
    # Horizontal PD: 10 cm error -> 0.3 m/s^2 (~1.8 deg lean); damping 3 /s keeps it just under
    # critical with the ~0.1 s command path (HTTP + firmware frame + APM attitude loop). Stiff
    # enough to hold +-0.15 m against 0.15 m/s^2 gusts and a 0.5 deg trim error (hilrig tests).
    pos_p_per_s2: float = 3.0
    vel_d_per_s: float = 3.0
    max_lean_rad: float = math.radians(15.0)  # gentle indoor flying
    # Altitude: 1 m error -> 1 m/s climb, capped at 0.8 m/s.
    alt_p_per_s: float = 1.0
    max_climb_mps: float = 0.8
    yaw_p_per_s: float = 1.5


def _angle_to_stick(angle_rad: float) -> int:
    frac = max(-1.0, min(1.0, angle_rad / ANGLE_MAX_RAD))
    if frac == 0:
        return 1500
    span = 500 - STICK_DEADZONE_US
    return int(round(1500 + math.copysign(STICK_DEADZONE_US + abs(frac) * span, frac)))


def _climb_to_throttle(rate_mps: float) -> int:
    # Inverse of ArduCopter's AltHold mapping (fc_emulator.emulator._run_mode).
    frac = max(-1.0, min(1.0, rate_mps / PILOT_SPEED_UP_MPS))
    if abs(rate_mps) < 1e-3:
        return 1500
    band = 500 - THR_DZ
    thr = 500 + math.copysign(THR_DZ + abs(frac) * band, frac)
    return int(round(1000 + thr))


def sticks_for(
    s: FcSnapshot,
    target_ned_m,
    target_yaw_rad: float,
    gains: PilotGains = PilotGains(),  # noqa: B008 (frozen dataclass: an immutable default)
) -> tuple[int, int, int, int]:
    """RC pulses (roll, pitch, throttle, yaw) steering the craft towards target_ned_m /
    target_yaw."""
    n_err = target_ned_m[0] - s.pos_ned_m[0]
    e_err = target_ned_m[1] - s.pos_ned_m[1]
    a_n = gains.pos_p_per_s2 * n_err - gains.vel_d_per_s * s.vel_ned_mps[0]
    a_e = gains.pos_p_per_s2 * e_err - gains.vel_d_per_s * s.vel_ned_mps[1]
    cy, sy = math.cos(s.yaw_rad), math.sin(s.yaw_rad)
    a_fwd = cy * a_n + sy * a_e
    a_right = -sy * a_n + cy * a_e
    lim = gains.max_lean_rad
    pitch = max(-lim, min(lim, -math.atan2(a_fwd, GRAVITY_MSS)))  # nose down to go forward
    roll = max(-lim, min(lim, math.atan2(a_right, GRAVITY_MSS)))
    alt_err = -target_ned_m[2] - s.altitude_m
    climb = max(-gains.max_climb_mps, min(gains.max_climb_mps, gains.alt_p_per_s * alt_err))
    yaw_rate = max(
        -YAW_RATE_MAX_RAD_S,
        min(YAW_RATE_MAX_RAD_S, gains.yaw_p_per_s * wrap_pi(target_yaw_rad - s.yaw_rad)),
    )
    yaw_frac = yaw_rate / YAW_RATE_MAX_RAD_S
    yaw_us = (
        1500
        if abs(yaw_frac) < 1e-3
        else int(
            round(
                1500
                + math.copysign(
                    STICK_DEADZONE_US + abs(yaw_frac) * (500 - STICK_DEADZONE_US), yaw_frac
                )
            )
        )
    )
    return (_angle_to_stick(roll), _angle_to_stick(pitch), _climb_to_throttle(climb), yaw_us)
