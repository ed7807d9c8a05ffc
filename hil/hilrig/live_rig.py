"""Real-time HIL rig: the firmware image in simavr (fw_sim --interactive, via hil/arduino's
LiveSession) in lock-step with the FC emulator, paced to the wall clock so real processes (HTTP
clients through the WiFi-bridge emulator, quad-control) can talk to it.

Each step (step_us of simulated time, run when the paced clock reaches it): inject the next queued
bridge request line (one in flight at a time, as the bridge chip does), feed the FC emulator's
MAVLink bytes to the telemetry pin, simulate the firmware to the step's end, feed every measured RC
pulse to the FC emulator, advance it, and resolve the request whose reply line arrived.
The wall clock is read only here, through the `clock` passed in (the adapter between simulated time
and the real processes); everything below it stays simulated. If the machine cannot keep up, the rig
never races to catch up (simulated time running faster than the clients' wall time would make a
client's ordinary delay look like a long silence to the firmware's failsafe): a lag beyond
MAX_LAG_S is dropped, so the simulation simply runs slower than real time (realtime_factor < 1).
Thread safety: transact()/snapshot()/history() may be called from any thread; one rig thread.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from arduino.simavr_session import LiveSession, firmware_elf
from fc_emulator import FcOptions, FcSnapshot, FlightControllerEmulator, QuadParams

from hilrig.paths import find_binary

# Largest lag behind the wall clock the rig makes up for (one 20 ms RC frame); beyond it the lag is
# dropped rather than caught up at simavr's ~3.7x speed.
MAX_LAG_S = 0.02


@dataclass
class _Pending:
    line: str
    done: threading.Event = field(default_factory=threading.Event)
    reply: str | None = None
    injected_us: float | None = None
    reply_end_us: float | None = None
    abandoned: bool = False


@dataclass(frozen=True)
class LineTiming:
    """Simulated times of one bridge request: injected on the serial link, reply complete, and the
    rise of the first throttle pulse after the reply (when the new command reaches the APM);
    `line` is the request line (its seq= ties it to the ground station's flight log)."""

    injected_us: float
    reply_end_us: float
    first_pulse_after_us: float | None
    line: str = ""


class LiveRig:
    def __init__(
        self,
        key_record: bytes,
        fc_options: FcOptions | None = None,
        quad_params: QuadParams | None = None,
        step_us: int = 5000,
        time_scale: float = 1.0,
        workdir=None,
        clock=time.monotonic,
    ) -> None:
        binary, elf = find_binary("fw_sim"), firmware_elf()
        if binary is None or elf is None:
            raise FileNotFoundError(
                "fw_sim or the firmware .elf is not built (make build / make firmware)"
            )
        if not step_us > 0 or not time_scale > 0:
            raise ValueError("step_us and time_scale must be > 0")
        self._session = LiveSession(key_record, workdir, fw_sim=binary, elf=elf)
        self._mav: list[tuple[int, bytes]] = []
        self.fc = FlightControllerEmulator(
            sink=lambda t, d: self._mav.append((t, d)), options=fc_options, params=quad_params
        )
        self.step_us = step_us
        self.time_scale = time_scale
        self._clock = clock
        self._lock = threading.Lock()
        self._queue: deque[_Pending] = deque()
        self._inflight: _Pending | None = None
        self._history: list[FcSnapshot] = []
        self._timings: list[LineTiming] = []
        self._awaiting_pulse: list[tuple[float, float, str]] = []
        # (simulated us at the end of a step, clock() right after it): maps simulated instants to
        # the wall clock the real processes live on (sim_to_wall).
        self._step_walls: list[tuple[int, float]] = []
        self._stop = threading.Event()
        self._error: BaseException | None = None
        self.sim_us = 0
        self.wall_s = 0.0
        self.lag_dropped_s = 0.0
        # Diagnosis of command gaps (the firmware's 250 ms failsafe counts simulated time): each lag
        # drop above one step (simulated us, wall s, dropped s), and every long simulated gap
        # between
        # two lines injected on the serial link (_note_injection).
        self.lag_events: list[tuple[int, float, float]] = []
        self._last_injected_us: float | None = None
        self.injection_gaps: list[dict] = []
        # Back-to-back fault: while > 0, the bridge forwards each request with this many
        # `GET /status` lines right behind it, as one burst of bytes (a second HTTP client on the
        # bridge, e.g. a telemetry poller, whose requests the chip queues and forwards without
        # waiting). The firmware keeps three back to back (docs/firmware.md, Receive path), so
        # 1-2 extra lines must cost nothing. Set from any thread; read by the rig thread.
        self.back_to_back_extra = 0
        self.bursts_sent = 0
        self._burst_replies_left = 0  # extra replies still due; no new line until they are in
        self._burst_sent_us = 0.0
        self._thread = threading.Thread(target=self._run, name="live-rig", daemon=True)

    # ---- API ------------------------------------------------------------------------------------
    def start(self) -> "LiveRig":
        self._thread.start()
        return self

    def transact(self, line: str, timeout_s: float) -> str | None:
        """Sends one line on the firmware's serial link; the reply line, or None after timeout_s."""
        p = _Pending(line)
        with self._lock:
            self._queue.append(p)
        if not p.done.wait(timeout_s):
            with self._lock:
                p.abandoned = True
                if p in self._queue:
                    self._queue.remove(p)
            return None
        return p.reply

    def snapshot(self) -> FcSnapshot:
        with self._lock:
            return self._history[-1] if self._history else self.fc.snapshot()

    def history(self) -> list[FcSnapshot]:
        with self._lock:
            return list(self._history)

    def forget_before(self, sim_us: float) -> None:
        """Drops the snapshots, step times and line timings of simulated instants before sim_us
        (lag_events and injection_gaps stay: one entry per rare stall). A rig that lives for hours
        (the soak: 200 snapshots a second, 476 MB after 30 minutes when all were kept) calls it
        once the earlier data has been scored; history(), timings() and sim_to_wall() then cover
        sim_us onwards only."""
        with self._lock:
            self._history = [s for s in self._history if s.t_us >= sim_us]
            self._step_walls = [w for w in self._step_walls if w[0] >= sim_us]
            self._timings = [t for t in self._timings if t.injected_us >= sim_us]

    def timings(self) -> list[LineTiming]:
        with self._lock:
            return list(self._timings)

    def sim_to_wall(self, sim_us) -> np.ndarray:
        """Wall-clock time (the `clock` passed in, time.monotonic by default) at which simulated
        instant(s) sim_us happened: interpolated between the rig's steps (each step is simulated in
        a burst at its due time, so the error is below one step, 5 ms by default)."""
        with self._lock:
            steps = np.array(self._step_walls, dtype=float)
        if len(steps) < 2:
            raise ValueError("the rig has not run two steps yet")
        return np.interp(np.asarray(sim_us, dtype=float), steps[:, 0], steps[:, 1])

    def wait_sim(self, t_us: float, timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while self.sim_us < t_us and time.monotonic() < end and self._thread.is_alive():
            time.sleep(0.01)
        return self.sim_us >= t_us

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall second since start (< 1 when the machine could not keep
        up)."""
        return (self.sim_us / 1e6) / self.wall_s if self.wall_s > 0 else 0.0

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=10)
        self._session.close()
        if self._error is not None:
            raise RuntimeError(f"live rig failed: {self._error!r}") from self._error

    def __enter__(self) -> "LiveRig":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- rig thread
    # -------------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            wall0 = self._clock()
            wall_start = wall0
            while not self._stop.is_set():
                t_next = self.sim_us + self.step_us
                due_wall = wall0 + t_next / 1e6 / self.time_scale
                now = self._clock()
                if now < due_wall:
                    time.sleep(min(due_wall - now, 0.002))
                    continue
                if now - due_wall > MAX_LAG_S:
                    dropped = now - due_wall - MAX_LAG_S
                    wall0 += dropped
                    self.lag_dropped_s += dropped
                    if dropped > self.step_us / 1e6:
                        self.lag_events.append((self.sim_us, now, round(dropped, 4)))
                self._step(t_next)
                self.wall_s = self._clock() - wall_start
        except BaseException as e:  # reported by close(); nothing escapes the thread
            self._error = e

    # A gap between injected lines this long (simulated us) is recorded: two keep-alive periods of
    # quad-control (50 ms), 40 % of the firmware's 250 ms failsafe (as quad-control's own gap log).
    INJECTION_GAP_US = 100_000
    # A burst's replies all arrive within ~3 x 11 ms (docs/firmware.md: ~10.6 ms per request at
    # 1 Mbaud); one missing after 100 ms was dropped (the firmware keeps three back to back).
    BURST_REPLY_TIMEOUT_US = 100_000

    def _note_injection(self, t_us: float) -> None:
        """Caller holds the lock. Records a long simulated gap since the previous injected line,
        with the lag the rig dropped meanwhile (a stalled rig shows as lag) and the lines still
        queued."""
        last = self._last_injected_us
        self._last_injected_us = t_us
        if last is None or t_us - last <= self.INJECTION_GAP_US:
            return
        lag = sum(d for sim, _, d in self.lag_events if last <= sim <= t_us)
        self.injection_gaps.append(
            {
                "sim_s": round(last / 1e6, 3),
                "gap_ms": round((t_us - last) / 1e3, 1),
                "rig_lag_dropped_ms": round(lag * 1e3, 1),
                "queued": len(self._queue),
            }
        )

    def _step(self, t_next: int) -> None:
        s = self._session
        with self._lock:
            if (
                self._burst_replies_left
                and self.sim_us - self._burst_sent_us > self.BURST_REPLY_TIMEOUT_US
            ):
                # A line of the burst was dropped by the firmware (no reply comes): the bridge
                # gives up on it, as on any request lost on the wire.
                if self._inflight is not None and self._inflight.injected_us == self._burst_sent_us:
                    self._inflight.done.set()
                    self._inflight = None
                self._burst_replies_left = 0
            if self._inflight is None and not self._burst_replies_left:
                while self._queue and self._queue[0].abandoned:
                    self._queue.popleft()
                if self._queue:
                    self._inflight = self._queue.popleft()
                    self._inflight.injected_us = max(float(self.sim_us), s.now_us)
                    self._note_injection(self._inflight.injected_us)
                    extra = max(0, int(self.back_to_back_extra))
                    if extra:
                        burst = self._inflight.line + "\n" + "GET /status\n" * extra
                        s.raw(self._inflight.injected_us, burst.encode())
                        self._burst_replies_left = extra
                        self._burst_sent_us = self._inflight.injected_us
                        self.bursts_sent += 1
                    else:
                        s.req(self._inflight.injected_us, self._inflight.line)
        for t, data in self._mav:
            s.mav(t, data)
        self._mav.clear()
        res = s.run(t_next)
        for p in sorted(res.pulses, key=lambda q: q.rise_us + q.width_us):
            end = int(p.rise_us + p.width_us)
            self.fc.advance_to(end)
            self.fc.feed_pulse(p.channel - 1, p.width_us, end)
            if p.channel == 3 and self._awaiting_pulse:
                with self._lock:
                    for inj, rep, line in self._awaiting_pulse:
                        if p.rise_us >= rep:
                            self._timings.append(LineTiming(inj, rep, p.rise_us, line))
                    self._awaiting_pulse = [a for a in self._awaiting_pulse if p.rise_us < a[1]]
        self.fc.advance_to(t_next)
        snap = self.fc.snapshot()
        wall = self._clock()
        with self._lock:
            self.sim_us = t_next
            self._step_walls.append((t_next, wall))
            self._history.append(snap)
            for r in res.replies:
                p = self._inflight
                self._inflight = None
                if p is None:
                    # The reply to a burst's extra line (or a stray one): nobody waits for it.
                    self._burst_replies_left = max(0, self._burst_replies_left - 1)
                    continue
                p.reply = r.text
                p.reply_end_us = r.end_us
                if p.injected_us is not None:
                    self._awaiting_pulse.append((p.injected_us, r.end_us, p.line))
                p.done.set()
