"""Quadcopter rigid-body model: attitude loop, thrust, gravity, drag, ground contact, battery sag.

Frames and conventions (ArduPilot's): world is NED (x north, y east, z down, metres); body is FRD;
attitude is ZYX Euler (yaw, then pitch, then roll), radians, roll right-wing-down positive, pitch
nose-up positive, yaw clockwise from north. `altitude_m` = -z.

The attitude loop lumps ArduCopter's angle P controller, its rate loop and the airframe's rotational
inertia into: angle error -> rate target (P, rate-limited) -> body rate following it with a
first-order
lag. Motors follow the commanded output with a first-order lag (ESC + propeller spin-up).
Disturbances (off by default): indoor air currents as a first-order Gauss-Markov acceleration per
horizontal axis (std `gust_accel_std_mss`, correlation time `gust_tau_s`, seeded by
`disturbance_seed`)
and an accelerometer level-trim error (`trim_error_deg`: the APM holds "level" that far off, so the
craft drifts until the position loop leans against it).
Time is passed in: `step(dt_s, ...)`; the model never reads a clock; its only randomness is the
seeded gust generator. Not thread-safe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

GRAVITY_MSS = 9.80665


@dataclass(frozen=True)
class QuadParams:
    # 1.5 kg: an F450-class frame with APM 2.6, 3S battery, companion board and a stripped Kinect
    # v1.
    mass_kg: float = 1.5
    # Hover at half output (ArduCopter MOT_THST_HOVER default 0.35..0.5; 0.5 makes mid-stick hover
    # in Stabilize with a linear throttle curve): max thrust = weight / hover_output.
    hover_output: float = 0.5
    # Motor/ESC/prop spin-up time constant ~40 ms for 10" props (measured figures for such motors
    # are 30-60 ms).
    motor_tau_s: float = 0.04
    # ArduCopter ATC_ANG_RLL_P / ATC_ANG_PIT_P default 4.5 (1/s): angle error -> rate target.
    angle_p_per_s: float = 4.5
    # Rate limit on the angle loop's output: ATC_RATE_R_MAX-like 3 rad/s (~170 deg/s) for a gentle
    # tune.
    max_tilt_rate_rad_s: float = 3.0
    # Closed rate loop + rotational inertia lumped as a 50 ms lag (a typical well-tuned 450 frame).
    rate_tau_s: float = 0.05
    # Yaw has far less control authority: 150 ms lag.
    yaw_rate_tau_s: float = 0.15
    # Linear (rotor/"induced") drag, N per m/s: dominant at indoor speeds (< 2 m/s).
    drag_linear_n_per_mps: float = 0.35
    # Quadratic body drag, N per (m/s)^2: with the linear term gives ~6 m/s terminal horizontal
    # speed at 22.5 deg lean (the firmware's hard roll/pitch limit).
    drag_quadratic_n_per_mps2: float = 0.1
    # Battery sag (optional): a 3S 2200 mAh LiPo. Thrust at a given output scales with (V /
    # V_full)^2.
    battery_sag: bool = False
    battery_full_v: float = 12.6
    battery_empty_v: float = 10.5
    battery_capacity_mah: float = 2200.0
    battery_internal_ohm: float = 0.03
    # Current drawn at full output (4 motors): ~60 A for this class; hover draws ~ (0.5)^1.5 * 60 =
    # 21 A.
    battery_full_output_a: float = 60.0
    # Disturbances (0 = off). Indoors: 0.3 m/s^2 gusts (~2 deg of lean to reject) with 2 s
    # correlation are what a 450 frame feels from its own prop wash off walls and room drafts.
    gust_accel_std_mss: float = 0.0
    gust_tau_s: float = 2.0
    trim_error_deg: tuple[float, float] = (0.0, 0.0)  # (roll, pitch) level-calibration error
    disturbance_seed: int = 1

    def validate(self) -> None:
        """Raises ValueError naming the first invalid field."""
        positive = [
            "mass_kg",
            "motor_tau_s",
            "angle_p_per_s",
            "max_tilt_rate_rad_s",
            "rate_tau_s",
            "yaw_rate_tau_s",
            "battery_full_v",
            "battery_empty_v",
            "battery_capacity_mah",
            "battery_full_output_a",
            "gust_tau_s",
        ]
        for name in positive:
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"QuadParams.{name} must be finite and > 0, got {v}")
        if len(self.trim_error_deg) != 2 or not all(
            math.isfinite(v) and abs(v) < 10 for v in self.trim_error_deg
        ):
            raise ValueError(
                "QuadParams.trim_error_deg must be two angles under 10 deg, "
                f"got {self.trim_error_deg}"
            )
        for name in [
            "drag_linear_n_per_mps",
            "drag_quadratic_n_per_mps2",
            "battery_internal_ohm",
            "gust_accel_std_mss",
        ]:
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"QuadParams.{name} must be finite and >= 0, got {v}")
        if not 0.1 <= self.hover_output <= 0.9:
            raise ValueError(
                f"QuadParams.hover_output must be in [0.1, 0.9], got {self.hover_output}"
            )
        if self.battery_empty_v >= self.battery_full_v:
            raise ValueError("QuadParams.battery_empty_v must be below battery_full_v")

    @property
    def max_thrust_n(self) -> float:
        return self.mass_kg * GRAVITY_MSS / self.hover_output


@dataclass
class QuadState:
    pos_ned_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vel_ned_mps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0
    rate_body_rad_s: np.ndarray = field(default_factory=lambda: np.zeros(3))  # p, q, r
    motor_output: float = 0.0  # 0..1, after the motor lag
    accel_ned_mss: np.ndarray = field(default_factory=lambda: np.zeros(3))  # last kinematic accel
    on_ground: bool = True
    battery_used_mah: float = 0.0
    battery_v: float = 12.6

    @property
    def altitude_m(self) -> float:
        return float(-self.pos_ned_m[2])

    def copy(self) -> "QuadState":
        return replace(
            self,
            pos_ned_m=self.pos_ned_m.copy(),
            vel_ned_mps=self.vel_ned_mps.copy(),
            rate_body_rad_s=self.rate_body_rad_s.copy(),
            accel_ned_mss=self.accel_ned_mss.copy(),
        )


def rotation_body_to_ned(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R such that v_ned = R @ v_body (ZYX Euler)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def wrap_pi(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class QuadModel:
    """The airframe. `step()` advances it by dt_s under attitude targets and a motor output."""

    def __init__(self, params: QuadParams | None = None, state: QuadState | None = None) -> None:
        self.params = params or QuadParams()
        self.params.validate()
        self.state = state or QuadState(battery_v=self.params.battery_full_v)
        # Set on every airborne -> ground transition: vertical speed (m/s, positive down) at
        # contact.
        self.touchdowns_mps: list[float] = []
        self._gust_rng = np.random.default_rng(self.params.disturbance_seed)
        self.gust_mss = np.zeros(3)

    def thrust_n(self) -> float:
        p, s = self.params, self.state
        scale = (s.battery_v / p.battery_full_v) ** 2 if p.battery_sag else 1.0
        return s.motor_output * p.max_thrust_n * scale

    def step(
        self,
        dt_s: float,
        roll_target_rad: float,
        pitch_target_rad: float,
        yaw_rate_target_rad_s: float,
        output_cmd: float,
    ) -> None:
        """Advance by dt_s (> 0). output_cmd is the mixer's collective output 0..1 (clamped)."""
        if not dt_s > 0 or not math.isfinite(dt_s):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s}")
        p, s = self.params, self.state
        if not all(
            math.isfinite(v)
            for v in (roll_target_rad, pitch_target_rad, yaw_rate_target_rad_s, output_cmd)
        ):
            raise ValueError("non-finite attitude target or output command")
        output_cmd = min(max(output_cmd, 0.0), 1.0)

        # Motors.
        s.motor_output += (output_cmd - s.motor_output) * min(1.0, dt_s / p.motor_tau_s)

        # Attitude loop (on the ground the legs hold the frame level and stop yaw).
        if s.on_ground and self.thrust_n() < p.mass_kg * GRAVITY_MSS:
            s.roll_rad = s.pitch_rad = 0.0
            s.rate_body_rad_s[:] = 0.0
        else:
            lim = p.max_tilt_rate_rad_s
            # A level-trim error makes the APM hold its "level" that far off the true level.
            roll_target_rad += math.radians(p.trim_error_deg[0])
            pitch_target_rad += math.radians(p.trim_error_deg[1])
            rate_tgt = np.array(
                [
                    min(max(p.angle_p_per_s * (roll_target_rad - s.roll_rad), -lim), lim),
                    min(max(p.angle_p_per_s * (pitch_target_rad - s.pitch_rad), -lim), lim),
                    yaw_rate_target_rad_s,
                ]
            )
            taus = np.array([p.rate_tau_s, p.rate_tau_s, p.yaw_rate_tau_s])
            s.rate_body_rad_s += (rate_tgt - s.rate_body_rad_s) * np.minimum(1.0, dt_s / taus)
            # Small-angle Euler-rate kinematics are enough for |tilt| < 45 deg.
            s.roll_rad += s.rate_body_rad_s[0] * dt_s
            s.pitch_rad += s.rate_body_rad_s[1] * dt_s
            s.yaw_rad = wrap_pi(s.yaw_rad + s.rate_body_rad_s[2] * dt_s)

        # Translation: thrust along body -z, gravity, drag.
        rot = rotation_body_to_ned(s.roll_rad, s.pitch_rad, s.yaw_rad)
        thrust = rot @ np.array([0.0, 0.0, -self.thrust_n()])
        v = s.vel_ned_mps
        speed = float(np.linalg.norm(v))
        drag = -p.drag_linear_n_per_mps * v - p.drag_quadratic_n_per_mps2 * speed * v
        accel = (thrust + drag) / p.mass_kg + np.array([0.0, 0.0, GRAVITY_MSS])
        if p.gust_accel_std_mss > 0:
            # Exact discretisation of the Gauss-Markov process (stationary std gust_accel_std_mss).
            a = math.exp(-dt_s / p.gust_tau_s)
            w = self._gust_rng.standard_normal(2) * p.gust_accel_std_mss * math.sqrt(1.0 - a * a)
            self.gust_mss[:2] = a * self.gust_mss[:2] + w
            if not s.on_ground:
                accel = accel + self.gust_mss

        if s.on_ground:
            if accel[2] < 0.0:  # net upward force: lift-off
                s.on_ground = False
            else:
                accel[:] = 0.0
                s.vel_ned_mps[:] = 0.0
        if not s.on_ground:
            s.vel_ned_mps = v + accel * dt_s
            s.pos_ned_m = s.pos_ned_m + s.vel_ned_mps * dt_s
            if s.pos_ned_m[2] >= 0.0:  # ground contact (z down): the floor stops the craft
                self.touchdowns_mps.append(float(s.vel_ned_mps[2]))
                s.pos_ned_m[2] = 0.0
                s.vel_ned_mps[:] = 0.0
                s.on_ground = True
        s.accel_ned_mss = accel

        # Battery.
        if p.battery_sag:
            current_a = p.battery_full_output_a * s.motor_output**1.5
            s.battery_used_mah += current_a * dt_s * 1000.0 / 3600.0
            soc = max(0.0, 1.0 - s.battery_used_mah / p.battery_capacity_mah)
            ocv = p.battery_empty_v + (p.battery_full_v - p.battery_empty_v) * soc
            s.battery_v = ocv - current_a * p.battery_internal_ohm

    def specific_force_body_mss(self) -> np.ndarray:
        """What an accelerometer in the body frame reads (FRD): R^T (a - g). Level at rest:
        (0,0,-g)."""
        s = self.state
        rot = rotation_body_to_ned(s.roll_rad, s.pitch_rad, s.yaw_rad)
        return rot.T @ (s.accel_ned_mss - np.array([0.0, 0.0, GRAVITY_MSS]))
