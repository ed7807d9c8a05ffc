"""Flies the FC emulator through a plan and records what the emulated Kinect sees.

Events run in simulated-time order: RC frames every 20 ms (the firmware's 50 Hz PWM frame) carry the
pilot's sticks; Kinect captures on the sensor's own fps grid render the camera pose at that instant.
Everything is deterministic (seeded emulators, no clock).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from fc_emulator import FlightControllerEmulator
from fc_emulator.emulator import RC_READ_PERIOD_US
from kinect_emulator import KinectEmulator, camera_pose_from_ned

from hilrig.pilot import ARM_STICKS_US, IDLE_STICKS_US, PilotGains, sticks_for


@dataclass(frozen=True)
class Leg:
    """Fly towards target (NED metres from take-off, yaw rad) for duration_s."""

    target_ned_m: tuple[float, float, float]
    yaw_rad: float
    duration_s: float
    # Vertical speed limit for this leg (None: the pilot's default); a landing leg uses a slow one.
    max_climb_mps: float | None = None
    # Landing leg: once the craft is on the ground, the ground station disarms.
    land: bool = False

    def gains(self, base: PilotGains) -> PilotGains:
        return (
            base if self.max_climb_mps is None else replace(base, max_climb_mps=self.max_climb_mps)
        )


@dataclass
class FlightLog:
    t_us: list[int] = field(default_factory=list)
    pos_ned_m: list[tuple[float, float, float]] = field(default_factory=list)
    target_ned_m: list[tuple[float, float, float]] = field(default_factory=list)
    frames: int = 0

    def array(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.array(self.t_us), np.array(self.pos_ned_m), np.array(self.target_ned_m)


@dataclass(frozen=True)
class CameraMount:
    mount_pitch_down_deg: float = 30.0
    # Body centre at take-off in the room frame (x north, y west, z up): 20 cm above the floor
    # (landing
    # gear), placed so the walls stay within the Kinect's 4.5 m range for the scenario plans.
    origin_room_m: tuple[float, float, float] = (-1.5, 0.5, 0.2)


def arm(fc: FlightControllerEmulator, on_sticks=None) -> None:
    """Holds the arming gesture until the emulator arms (ArduCopter: 2 s); raises if it never
    does."""
    deadline = fc.t_us + 5_000_000
    while not fc.armed:
        if fc.t_us >= deadline:
            raise RuntimeError("FC emulator did not arm within 5 s of the arming gesture")
        t = fc.t_us + RC_READ_PERIOD_US
        fc.feed_rc(ARM_STICKS_US, t)
        if on_sticks is not None:
            on_sticks(t, ARM_STICKS_US)
        fc.advance_to(t)
    fc.feed_rc(IDLE_STICKS_US, fc.t_us)


def fly_plan(
    fc: FlightControllerEmulator,
    legs: list[Leg],
    kinect: KinectEmulator | None = None,
    sink=None,
    mount: CameraMount = CameraMount(),  # noqa: B008 (frozen dataclass: an immutable default)
    gains: PilotGains = PilotGains(),  # noqa: B008 (frozen dataclass)
    log: FlightLog | None = None,
    on_sticks=None,
) -> FlightLog:
    """Flies each leg with the ground-truth pilot; renders Kinect frames into `sink(frame)` if
    given; `on_sticks(t_us, sticks)` sees every RC frame the pilot sends (to replay it through
    firmware)."""
    log = log or FlightLog()
    for leg in legs:
        end_us = fc.t_us + int(round(leg.duration_s * 1e6))
        next_rc = fc.t_us + RC_READ_PERIOD_US
        last_cam_us = (
            fc.t_us
        )  # captures strictly after this (the FC's 2.5 ms tick may lag behind it)
        while fc.t_us < end_us:
            next_cam = kinect.frames_due(last_cam_us, end_us)[:1] if kinect is not None else []
            if next_cam and next_cam[0] <= next_rc:
                last_cam_us = next_cam[0]
                fc.advance_to(next_cam[0])
                s = fc.snapshot()
                T = camera_pose_from_ned(
                    s.pos_ned_m,
                    s.roll_rad,
                    s.pitch_rad,
                    s.yaw_rad,
                    mount.mount_pitch_down_deg,
                    origin_room_m=mount.origin_room_m,
                )
                frame = kinect.render(T, next_cam[0])
                log.frames += 1
                if sink is not None:
                    sink(frame)
                continue
            t = min(next_rc, end_us)
            fc.advance_to(t)
            s = fc.snapshot()
            sticks = sticks_for(s, leg.target_ned_m, leg.yaw_rad, leg.gains(gains))
            fc.feed_rc(sticks, t)
            if on_sticks is not None:
                on_sticks(t, sticks)
            log.t_us.append(t)
            log.pos_ned_m.append(s.pos_ned_m)
            log.target_ned_m.append(tuple(leg.target_ned_m))
            next_rc = t + RC_READ_PERIOD_US
            if t == end_us:
                break
    return log


def hold_error_m(log: FlightLog, from_us: int, to_us: int) -> dict:
    """3-D and horizontal position error statistics against the target over [from_us, to_us]."""
    t, p, g = log.array()
    sel = (t >= from_us) & (t <= to_us)
    err = p[sel] - g[sel]
    e3 = np.linalg.norm(err, axis=1)
    return {
        "max_m": float(e3.max()),
        "rms_m": float(math.sqrt(np.mean(e3**2))),
        "max_vertical_m": float(np.abs(err[:, 2]).max()),
        "samples": int(sel.sum()),
    }
