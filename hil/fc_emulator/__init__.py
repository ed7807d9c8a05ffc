"""APM 2.6 / ArduCopter flight-controller emulator for the hardware-in-loop rig.

Reads the four RC channels as pulse widths (the harness feeds them from the simavr PWM pins), flies
a quadcopter model with simulation time passed in, applies ArduCopter's arming gesture and radio
failsafe, and emits HEARTBEAT / ATTITUDE / RAW_IMU as real MAVLink v2 bytes (pymavlink).
"""

from fc_emulator.emulator import FcOptions, FcSnapshot, FlightControllerEmulator, FlightMode, fly
from fc_emulator.quad_model import QuadModel, QuadParams, QuadState
from fc_emulator.rc_input import RcInput

__all__ = [
    "FlightControllerEmulator",
    "FcOptions",
    "FcSnapshot",
    "FlightMode",
    "fly",
    "QuadModel",
    "QuadParams",
    "QuadState",
    "RcInput",
]
