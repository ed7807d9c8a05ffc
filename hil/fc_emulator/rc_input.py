"""RC input of the emulated APM: the four channels as pulse widths with simulated timestamps.

The harness measures each pulse on the simavr PWM pins and calls `feed()` (or `feed_frame()` for a
whole 50 Hz frame). Pulses outside ArduPilot's valid window are dropped, as the APM's input-capture
decoder drops them, so a pin stuck low or a glitch never reaches the flight logic.
Channel order is ArduPilot's RC input order: 0 roll, 1 pitch, 2 throttle, 3 yaw.
Not thread-safe: feed and read from one thread (the scenario loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

CHANNEL_COUNT = 4
CH_ROLL, CH_PITCH, CH_THROTTLE, CH_YAW = 0, 1, 2, 3

# ArduPilot RC_Channel accepts pulses in [900, 2200] us (RC_MIN_LIMIT_PWM / RC_MAX_LIMIT_PWM);
# anything outside is treated as "no signal" on that channel.
VALID_PULSE_MIN_US = 900
VALID_PULSE_MAX_US = 2200
# Stick centre (RCx_TRIM default) and throttle low (RC3_MIN default): values before any pulse
# arrives.
NEUTRAL_US = 1500
THROTTLE_LOW_US = 1000


@dataclass(frozen=True)
class RcFrame:
    """Latest accepted pulse width per channel and when the newest of them arrived."""

    pulses_us: tuple[int, int, int, int]
    last_update_us: int | None  # None: no valid pulse seen yet


class RcInput:
    def __init__(self) -> None:
        self._pulses_us = [NEUTRAL_US, NEUTRAL_US, THROTTLE_LOW_US, NEUTRAL_US]
        self._last_update_us: int | None = None
        self._rejected = 0

    def feed(self, channel: int, width_us: float, t_us: int) -> bool:
        """One measured pulse on `channel` (0..3) of `width_us` ending at simulated time `t_us`.

        Returns False (and counts it) for an out-of-window or non-finite pulse; raises ValueError
        for a
        channel index that does not exist (a wiring bug in the caller, not a signal condition).
        """
        if not 0 <= channel < CHANNEL_COUNT:
            raise ValueError(f"RC channel {channel} out of range 0..{CHANNEL_COUNT - 1}")
        if not math.isfinite(width_us) or not VALID_PULSE_MIN_US <= width_us <= VALID_PULSE_MAX_US:
            self._rejected += 1
            return False
        self._pulses_us[channel] = int(round(width_us))
        if self._last_update_us is None or t_us > self._last_update_us:
            self._last_update_us = int(t_us)
        return True

    def feed_frame(self, widths_us, t_us: int) -> int:
        """All four channels at once (roll, pitch, throttle, yaw). Returns how many were
        accepted."""
        if len(widths_us) != CHANNEL_COUNT:
            raise ValueError(f"expected {CHANNEL_COUNT} pulse widths, got {len(widths_us)}")
        return sum(self.feed(ch, w, t_us) for ch, w in enumerate(widths_us))

    def frame(self) -> RcFrame:
        return RcFrame(tuple(self._pulses_us), self._last_update_us)  # type: ignore[arg-type]

    @property
    def rejected_count(self) -> int:
        return self._rejected
