"""ArduCopter-like flight logic around the quadcopter model, with MAVLink v2 telemetry out.

What is emulated (ArduCopter 3.x behaviour, parameters at their defaults unless noted):
  * RC mapping: roll/pitch stick -> lean angle (ANGLE_MAX 45 deg), yaw stick -> yaw rate
    (202.5 deg/s full stick), throttle -> Stabilize throttle curve or AltHold climb rate.
  * Arming by stick gesture: throttle at zero + yaw full right held ARM_DELAY (2 s); disarm with yaw
    full left, or automatically after landing in Land mode.
  * Radio failsafe (FS_THR_ENABLE = 3, "always Land"): throttle below FS_THR_VALUE (975 us) for
    FS_COUNTER consecutive RC reads, or no RC pulses for 500 ms -> Land mode, descending at
    LAND_SPEED (50 cm/s); if already landed, disarm at once.
  * Land detector: on the ground with the motors at their lower limit for 1 s -> landed.
Simplification (documented in docs/hil.md): there is no mode switch channel (the craft has only four
RC inputs), so the flight mode is an option; after a failsafe Land and disarm it returns to that
mode.

Time is passed in: `advance_to(t_us)` runs 400 Hz main-loop ticks up to t_us. Telemetry goes to a
sink callable `sink(t_us, data: bytes)` as real MAVLink v2 frames (pymavlink), each stamped with the
tick that produced it. Random IMU noise is drawn from a generator seeded by the options. Not
thread-safe.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from fc_emulator.quad_model import GRAVITY_MSS, QuadModel, QuadParams
from fc_emulator.rc_input import CH_PITCH, CH_ROLL, CH_THROTTLE, CH_YAW, RcInput

# ---- ArduCopter constants (names as in ArduCopter's parameters / source)
# ---------------------------
MAIN_LOOP_PERIOD_US = 2500  # 400 Hz: ArduCopter's main loop rate on the APM 2.x (SCHED_LOOP_RATE)
RC_READ_PERIOD_US = 20000  # RC is read at the 50 Hz frame rate of the receiver
FS_THR_VALUE_US = 975  # FS_THR_VALUE default
FS_COUNTER = 3  # radio.cpp: consecutive low-throttle reads before failsafe (60 ms)
FS_RADIO_TIMEOUT_US = 500_000  # no RC pulses for 500 ms -> failsafe (FS_RADIO_TIMEOUT_MS)
ARM_DELAY_US = 2_000_000  # motors.cpp ARM_DELAY: gesture held 2 s
ARM_THROTTLE_MAX_US = 1030  # throttle "at zero": RC3_MIN 1000 + RC3_DZ 30
ARM_YAW_RIGHT_MIN_US = (
    1900  # yaw control_in > 4000 of 4500 centi-degrees -> ~1944 us; 1900 with trims
)
DISARM_YAW_LEFT_MAX_US = 1100
ANGLE_MAX_RAD = math.radians(45.0)  # ANGLE_MAX 4500 cdeg
YAW_RATE_MAX_RAD_S = math.radians(202.5)  # 4.5 * 45 deg/s full stick (ACRO_YAW_P default)
STICK_DEADZONE_US = 20  # RC1/2/4_DZ default
THR_DZ = 100  # THR_DZ (of 1000): AltHold throttle dead band around mid-stick
PILOT_SPEED_UP_MPS = 2.5  # PILOT_VELZ_MAX 250 cm/s (up and down)
LAND_SPEED_MPS = 0.5  # LAND_SPEED 50 cm/s (below LAND_ALT_LOW, always the case indoors)
PSC_POSZ_P = 1.0  # altitude error (m) -> climb rate (m/s)
PSC_VELZ_P = 5.0  # climb rate error (m/s) -> acceleration (m/s^2)
PSC_VELZ_I = 1.0  # integral on the same error: learns hover output / battery sag
MOT_SPIN_ARM = 0.1  # motor output while armed on the ground
LAND_DETECT_US = 1_000_000  # land_detector: 1 s at the lower limit on the ground
LAND_DETECT_OUTPUT_FRACTION = 0.9  # "lower limit" = output below 90 % of the hover output
MAX_TILT_ANGLE_BOOST = 0.75  # angle boost only up to cos(tilt) >= 0.75 (ArduCopter limits boost)


class FlightMode(enum.IntEnum):
    """ArduCopter custom_mode numbers (HEARTBEAT.custom_mode)."""

    STABILIZE = 0
    ALT_HOLD = 2
    LAND = 9


@dataclass(frozen=True)
class FcOptions:
    mode: FlightMode = FlightMode.ALT_HOLD
    # Telemetry rates (Hz); ArduPilot's SRx_ stream rates. ATTITUDE at 25 Hz sits in the 10-50 Hz
    # range
    # ArduCopter is usually configured to; RAW_IMU at 10 Hz; HEARTBEAT is always 1 Hz.
    heartbeat_hz: float = 1.0
    attitude_hz: float = 25.0
    raw_imu_hz: float = 10.0
    # RAW_IMU noise: MPU-6000 on the APM 2.6, ~8 mg accel and ~0.05 rad/s gyro with motors running.
    accel_noise_mg: float = 8.0
    gyro_noise_mrad_s: float = 50.0
    seed: int = 1
    system_id: int = 1
    component_id: int = 1

    def validate(self) -> None:
        for name in ("heartbeat_hz", "attitude_hz", "raw_imu_hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 < v <= 400):
                raise ValueError(f"FcOptions.{name} must be in (0, 400] Hz, got {v}")
        for name in ("accel_noise_mg", "gyro_noise_mrad_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"FcOptions.{name} must be finite and >= 0, got {v}")
        if self.mode not in (FlightMode.STABILIZE, FlightMode.ALT_HOLD):
            raise ValueError(
                "FcOptions.mode must be STABILIZE or ALT_HOLD (LAND is entered by failsafe)"
            )


@dataclass(frozen=True)
class FcSnapshot:
    t_us: int
    armed: bool
    mode: FlightMode
    radio_failsafe: bool
    landed: bool
    pos_ned_m: tuple[float, float, float]
    vel_ned_mps: tuple[float, float, float]
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    motor_output: float
    battery_v: float

    @property
    def altitude_m(self) -> float:
        return -self.pos_ned_m[2]

    @property
    def climb_rate_mps(self) -> float:
        return -self.vel_ned_mps[2]


Sink = Callable[[int, bytes], None]


class _SinkFile:
    """pymavlink writes through file.write(); this forwards each frame to the sink with the tick
    time."""

    def __init__(self, sink: Sink) -> None:
        self.sink = sink
        self.t_us = 0

    def write(self, data: bytes) -> None:
        self.sink(self.t_us, bytes(data))


def _stick(pwm_us: int, dz_us: int = STICK_DEADZONE_US) -> float:
    """Centred stick -1..1 with ArduPilot's dead zone around 1500 us."""
    off = pwm_us - 1500
    if abs(off) <= dz_us:
        return 0.0
    off = off - dz_us if off > 0 else off + dz_us
    return max(-1.0, min(1.0, off / (500.0 - dz_us)))


def _throttle_in(pwm_us: int) -> float:
    """Throttle stick 0..1 (RC3_MIN 1000, RC3_MAX 2000)."""
    return max(0.0, min(1.0, (pwm_us - 1000) / 1000.0))


class FlightControllerEmulator:
    def __init__(
        self,
        sink: Sink | None = None,
        options: FcOptions | None = None,
        params: QuadParams | None = None,
        start_us: int = 0,
    ) -> None:
        self.options = options or FcOptions()
        self.options.validate()
        self.rc = RcInput()
        self.model = QuadModel(params or QuadParams())
        self._t_us = int(start_us)
        self._rng = np.random.default_rng(self.options.seed)
        self._sink_file = _SinkFile(sink or (lambda _t, _d: None))
        self._mav = mavlink2.MAVLink(
            self._sink_file,
            srcSystem=self.options.system_id,
            srcComponent=self.options.component_id,
        )
        self.armed = False
        self.mode = self.options.mode
        self.radio_failsafe = False
        self.landed = True
        self._fs_low_count = 0
        self._arm_gesture_since_us: int | None = None
        self._disarm_gesture_since_us: int | None = None
        self._landed_since_us: int | None = None
        self._next_rc_read_us = self._t_us
        self._alt_target_m = 0.0
        self._velz_integrator = 0.0
        self._roll_tgt = self._pitch_tgt = self._yaw_rate_tgt = 0.0
        self._throttle_pwm = 1000
        self._periods_us = {
            "heartbeat": int(round(1e6 / self.options.heartbeat_hz)),
            "attitude": int(round(1e6 / self.options.attitude_hz)),
            "raw_imu": int(round(1e6 / self.options.raw_imu_hz)),
        }
        self._next_msg_us = dict.fromkeys(self._periods_us, self._t_us)
        self.events: list[tuple[int, str]] = []  # (t_us, text): arming, failsafe, mode changes

    # ---- public API
    # -------------------------------------------------------------------------------
    @property
    def t_us(self) -> int:
        return self._t_us

    def feed_pulse(self, channel: int, width_us: float, t_us: int) -> bool:
        return self.rc.feed(channel, width_us, t_us)

    def feed_rc(self, widths_us, t_us: int) -> int:
        return self.rc.feed_frame(widths_us, t_us)

    def advance_to(self, t_us: int) -> None:
        """Run main-loop ticks until simulated time reaches t_us (never goes backwards)."""
        while self._t_us + MAIN_LOOP_PERIOD_US <= t_us:
            self._t_us += MAIN_LOOP_PERIOD_US
            self._tick()

    def snapshot(self) -> FcSnapshot:
        s = self.model.state
        return FcSnapshot(
            self._t_us,
            self.armed,
            self.mode,
            self.radio_failsafe,
            self.landed,
            tuple(float(v) for v in s.pos_ned_m),
            tuple(float(v) for v in s.vel_ned_mps),
            float(s.roll_rad),
            float(s.pitch_rad),
            float(s.yaw_rad),
            float(s.motor_output),
            float(s.battery_v),
        )

    @property
    def touchdowns_mps(self) -> list[float]:
        """Vertical speed (m/s, down positive) at each ground contact."""
        return self.model.touchdowns_mps

    # ---- main loop
    # --------------------------------------------------------------------------------
    def _tick(self) -> None:
        now = self._t_us
        if now >= self._next_rc_read_us:
            self._next_rc_read_us += RC_READ_PERIOD_US
            self._read_radio(now)
        output = self._run_mode(MAIN_LOOP_PERIOD_US * 1e-6)
        self.model.step(
            MAIN_LOOP_PERIOD_US * 1e-6, self._roll_tgt, self._pitch_tgt, self._yaw_rate_tgt, output
        )
        self._update_land_detector(now, output)
        self._send_telemetry(now)

    def _event(self, now: int, text: str) -> None:
        self.events.append((now, text))

    def _read_radio(self, now: int) -> None:
        frame = self.rc.frame()
        lost = frame.last_update_us is None or now - frame.last_update_us > FS_RADIO_TIMEOUT_US
        thr = frame.pulses_us[CH_THROTTLE]
        low = lost or thr < FS_THR_VALUE_US
        self._fs_low_count = min(self._fs_low_count + 1, FS_COUNTER) if low else 0
        if not self.radio_failsafe and self._fs_low_count >= FS_COUNTER:
            self.radio_failsafe = True
            self._event(now, "radio failsafe: " + ("no RC" if lost else f"throttle {thr} us"))
            if self.armed:
                if self.landed:
                    self._disarm(now, "failsafe while landed")
                else:
                    self._set_mode(now, FlightMode.LAND)
        elif self.radio_failsafe and not low:
            self.radio_failsafe = False
            self._event(now, "radio failsafe cleared")
        if self.radio_failsafe:
            self._roll_tgt = self._pitch_tgt = self._yaw_rate_tgt = 0.0
            self._throttle_pwm = 1000
            self._arm_gesture_since_us = self._disarm_gesture_since_us = None
            return
        roll, pitch, yaw = (
            frame.pulses_us[CH_ROLL],
            frame.pulses_us[CH_PITCH],
            frame.pulses_us[CH_YAW],
        )
        self._throttle_pwm = thr
        self._roll_tgt = _stick(roll) * ANGLE_MAX_RAD
        self._pitch_tgt = _stick(pitch) * ANGLE_MAX_RAD
        self._yaw_rate_tgt = _stick(yaw) * YAW_RATE_MAX_RAD_S
        self._arming_gesture(now, thr, yaw)

    def _arming_gesture(self, now: int, thr: int, yaw: int) -> None:
        thr_zero = thr <= ARM_THROTTLE_MAX_US
        if not self.armed and thr_zero and yaw >= ARM_YAW_RIGHT_MIN_US:
            if self._arm_gesture_since_us is None:
                self._arm_gesture_since_us = now
            elif now - self._arm_gesture_since_us >= ARM_DELAY_US:
                self._arm(now)
        else:
            self._arm_gesture_since_us = None
        if self.armed and thr_zero and self.landed and yaw <= DISARM_YAW_LEFT_MAX_US:
            if self._disarm_gesture_since_us is None:
                self._disarm_gesture_since_us = now
            elif now - self._disarm_gesture_since_us >= ARM_DELAY_US:
                self._disarm(now, "stick gesture")
        else:
            self._disarm_gesture_since_us = None

    def _arm(self, now: int) -> None:
        self.armed = True
        self._arm_gesture_since_us = None
        self._alt_target_m = self.model.state.altitude_m
        self._velz_integrator = 0.0
        self._event(now, f"armed in {self.mode.name}")

    def _disarm(self, now: int, why: str) -> None:
        self.armed = False
        self._disarm_gesture_since_us = None
        self._event(now, f"disarmed: {why}")
        if self.mode == FlightMode.LAND:
            self._set_mode(now, self.options.mode)

    def _set_mode(self, now: int, mode: FlightMode) -> None:
        if mode != self.mode:
            self.mode = mode
            self._alt_target_m = self.model.state.altitude_m
            self._event(now, f"mode {mode.name}")

    # ---- flight modes
    # -----------------------------------------------------------------------------
    def _run_mode(self, dt_s: float) -> float:
        """Collective motor output 0..1 for this tick."""
        if not self.armed:
            return 0.0
        p = self.model.params
        s = self.model.state
        if self.mode == FlightMode.LAND:
            self._roll_tgt = self._pitch_tgt = (
                0.0  # no position source: land level (no GPS indoors)
            )
            return self._climb_rate_controller(-LAND_SPEED_MPS, dt_s, hold_altitude=False)
        if self.mode == FlightMode.STABILIZE:
            thr_in = _throttle_in(self._throttle_pwm)
            if thr_in <= 0.0:
                return MOT_SPIN_ARM if self.landed else 0.0
            expo = min(max(-(p.hover_output - 0.5) / 0.375, -0.5), 1.0)
            out = thr_in * (1.0 - expo) + expo * thr_in**3
            return min(1.0, max(MOT_SPIN_ARM, out) / self._tilt_cos(s))
        # ALT_HOLD
        thr = _throttle_in(self._throttle_pwm) * 1000.0
        mid = 500.0
        if thr > mid + THR_DZ:
            rate = PILOT_SPEED_UP_MPS * (thr - mid - THR_DZ) / (1000.0 - mid - THR_DZ)
        elif thr < mid - THR_DZ:
            rate = -PILOT_SPEED_UP_MPS * (mid - THR_DZ - thr) / (mid - THR_DZ)
        else:
            rate = 0.0
        if self.landed and rate <= 0.0:
            self._alt_target_m = s.altitude_m
            self._velz_integrator = 0.0
            return MOT_SPIN_ARM
        return self._climb_rate_controller(rate, dt_s, hold_altitude=True)

    @staticmethod
    def _tilt_cos(s) -> float:
        return max(MAX_TILT_ANGLE_BOOST, math.cos(s.roll_rad) * math.cos(s.pitch_rad))

    def _climb_rate_controller(self, rate_mps: float, dt_s: float, hold_altitude: bool) -> float:
        """AC_PosControl-like z loop: altitude target integrates the pilot's climb rate."""
        p = self.model.params
        s = self.model.state
        alt = s.altitude_m
        climb = -float(s.vel_ned_mps[2])
        if hold_altitude:
            self._alt_target_m += rate_mps * dt_s
            # Leash: the target never runs more than 1 m away from the craft (AC_PosControl leash).
            self._alt_target_m = min(max(self._alt_target_m, alt - 1.0), alt + 1.0)
            vel_target = rate_mps + PSC_POSZ_P * (self._alt_target_m - alt)
        else:
            vel_target = rate_mps
        err = vel_target - climb
        out_unlimited_accel = PSC_VELZ_P * err + self._velz_integrator
        output = p.hover_output * (1.0 + out_unlimited_accel / GRAVITY_MSS) / self._tilt_cos(s)
        saturated = output <= MOT_SPIN_ARM or output >= 1.0
        if not saturated or (output >= 1.0 and err < 0) or (output <= MOT_SPIN_ARM and err > 0):
            self._velz_integrator += (
                PSC_VELZ_I * err * dt_s
            )  # anti-windup: integrate only unsaturated
        return min(max(output, MOT_SPIN_ARM), 1.0)

    def _update_land_detector(self, now: int, output: float) -> None:
        s = self.model.state
        # Motors at their lower limit: output below 90 % of hover (the z loop is pushing down on the
        # floor).
        at_lower_limit = output <= LAND_DETECT_OUTPUT_FRACTION * self.model.params.hover_output
        if self.armed and s.on_ground and at_lower_limit:
            if self._landed_since_us is None:
                self._landed_since_us = now
            if not self.landed and now - self._landed_since_us >= LAND_DETECT_US:
                self.landed = True
                self._event(now, "landed")
                if self.mode == FlightMode.LAND:
                    self._disarm(now, "landed in LAND")
        else:
            self._landed_since_us = None
            if not s.on_ground and self.landed:
                self.landed = False
                self._event(now, "took off")
        if not self.armed and s.on_ground:
            self.landed = True

    # ---- telemetry
    # --------------------------------------------------------------------------------
    def _send_telemetry(self, now: int) -> None:
        self._sink_file.t_us = now
        for name, period in self._periods_us.items():
            if now < self._next_msg_us[name]:
                continue
            self._next_msg_us[name] += period
            if self._next_msg_us[name] <= now:  # never burst to catch up
                self._next_msg_us[name] = now + period
            getattr(self, "_send_" + name)(now)

    def _send_heartbeat(self, now: int) -> None:
        base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.armed:
            base |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
        if self.radio_failsafe:
            status = mavlink2.MAV_STATE_CRITICAL
        else:
            status = mavlink2.MAV_STATE_ACTIVE if self.armed else mavlink2.MAV_STATE_STANDBY
        self._mav.heartbeat_send(
            mavlink2.MAV_TYPE_QUADROTOR,
            mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base,
            int(self.mode),
            status,
        )

    def _send_attitude(self, now: int) -> None:
        s = self.model.state
        r = s.rate_body_rad_s
        self._mav.attitude_send(
            now // 1000 & 0xFFFFFFFF,
            s.roll_rad,
            s.pitch_rad,
            s.yaw_rad,
            float(r[0]),
            float(r[1]),
            float(r[2]),
        )

    def _send_raw_imu(self, now: int) -> None:
        acc_mg = self.model.specific_force_body_mss() * 1000.0 / GRAVITY_MSS
        acc_mg = acc_mg + self._rng.normal(0.0, self.options.accel_noise_mg, 3)
        gyro = self.model.state.rate_body_rad_s * 1000.0
        gyro = gyro + self._rng.normal(0.0, self.options.gyro_noise_mrad_s, 3)
        a = [int(np.clip(round(v), -32768, 32767)) for v in acc_mg]
        g = [int(np.clip(round(v), -32768, 32767)) for v in gyro]
        self._mav.raw_imu_send(now, a[0], a[1], a[2], g[0], g[1], g[2], 0, 0, 0)


def fly(
    fc: "FlightControllerEmulator",
    pulses_us,
    duration_s: float,
    frame_period_us: int = RC_READ_PERIOD_US,
) -> None:
    """Feeds a constant RC frame every frame_period_us for duration_s and advances the emulator.

    A stand-in for the harness (tests and scenarios without the firmware in the loop); `pulses_us`
    None feeds nothing (RC link lost) while time still advances.
    """
    end_us = fc.t_us + int(round(duration_s * 1e6))
    t = fc.t_us
    while t < end_us:
        t = min(t + frame_period_us, end_us)
        if pulses_us is not None:
            fc.feed_rc(pulses_us, t)
        fc.advance_to(t)
