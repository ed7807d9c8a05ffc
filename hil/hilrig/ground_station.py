"""A ground station stand-in that talks to the craft the real way: signed `PUT /control` requests
over HTTP to the WiFi bridge at 50 Hz, sticks from the ground-truth pilot (position source: the
emulator's truth, where quad-control would use SLAM). Used where quad-control / slam-server are not
in the loop; the HTTP, MAC, sequence and reply handling are the protocol's (rgbd_protocol.control).

Runs on its own thread, paced by the wall clock passed in (it is a real-time client of the rig).
`kill()` stops it dead without a goodbye, as a crashed ground-station process would.
"""

from __future__ import annotations

import http.client
import threading
import time
from dataclasses import dataclass, field

from hilrig.flight import Leg
from hilrig.pilot import ARM_STICKS_US, IDLE_STICKS_US, PilotGains, sticks_for

COMMAND_PERIOD_S = 0.02  # 50 Hz, the thesis' command rate (quad-control's period_ms)
ARM_GESTURE_S = 2.4  # ArduCopter's 2 s arming delay + margin for the PWM frame delay
ARM_GIVE_UP_S = 15.0  # stop holding the gesture if the APM has not armed by then
# quad-control gives up after 100 ms; this stand-in waits 1 s so a loaded CI machine is not mistaken
# for a link fault (late replies are counted in round_trip_ms).
HTTP_TIMEOUT_S = 1.0


@dataclass
class GroundStationStats:
    sent: int = 0
    statuses: dict = field(default_factory=dict)
    round_trip_ms: list = field(default_factory=list)
    errors: int = 0


class _Client:
    """One keep-alive HTTP connection to the bridge with its own thread (quad-control has two)."""

    def __init__(self, gs: "GroundStation", name: str) -> None:
        self.gs = gs
        self.busy = threading.Event()
        self.job: tuple | None = None
        self.wake = threading.Event()
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)

    def submit(self, sticks, arm: bool) -> None:
        self.job = (sticks, arm, self.gs.seqs.next())
        self.busy.set()
        self.wake.set()

    def _run(self) -> None:
        from rgbd_protocol.control import build_control_request

        conn = http.client.HTTPConnection("127.0.0.1", self.gs.port, timeout=HTTP_TIMEOUT_S)
        while not self.gs._stop.is_set():
            if not self.wake.wait(0.05):
                continue
            self.wake.clear()
            sticks, arm, seq = self.job
            line = build_control_request(self.gs.key, seq, arm, *sticks)
            t0 = self.gs.clock()
            try:
                conn.request("PUT", line.split(" ", 1)[1])
                r = conn.getresponse()
                r.read()
                self.gs._record(r.status, (self.gs.clock() - t0) * 1e3)
            except (OSError, http.client.HTTPException):
                self.gs._record(None, None)
                conn.close()
                conn = http.client.HTTPConnection("127.0.0.1", self.gs.port, timeout=HTTP_TIMEOUT_S)
            self.busy.clear()
        conn.close()


class GroundStation:
    """Every COMMAND_PERIOD_S the latest command goes out on the next idle client (round robin, as
    quad-control's FirmwareLink does), so one stalled request never stops the commands."""

    def __init__(
        self,
        bridge_port: int,
        key: bytes,
        rig,
        plan: list[Leg],
        clock=time.monotonic,
        clients: int = 2,
    ) -> None:
        from rgbd_protocol.control import SequenceCounter

        self.port = bridge_port
        self.key = key
        self.rig = rig
        self.plan = plan
        self.clock = clock
        self.seqs = SequenceCounter()
        self.stats = GroundStationStats()
        self._stats_lock = threading.Lock()
        self._stop = threading.Event()
        self._clients = [_Client(self, f"gs-client-{i}") for i in range(clients)]
        self._next_client = 0
        self._thread = threading.Thread(target=self._run, name="ground-station", daemon=True)
        self.leg_index = 0
        self.disarmed_sim_us: int | None = None
        self.leg_started_sim_us: list[int] = []
        self.skipped_busy = 0

    def start(self) -> "GroundStation":
        for c in self._clients:
            c.thread.start()
        self._thread.start()
        return self

    def kill(self) -> None:
        """Stops dead, without a goodbye (a crashed ground-station process)."""
        self._stop.set()
        self._thread.join(timeout=5)
        for c in self._clients:
            c.thread.join(timeout=5)

    def _record(self, status, rtt_ms) -> None:
        with self._stats_lock:
            self.stats.sent += 1
            if status is None:
                self.stats.errors += 1
                return
            self.stats.statuses[status] = self.stats.statuses.get(status, 0) + 1
            self.stats.round_trip_ms.append(rtt_ms)

    def _send(self, sticks, arm: bool) -> None:
        for k in range(len(self._clients)):
            c = self._clients[(self._next_client + k) % len(self._clients)]
            if not c.busy.is_set():
                self._next_client = (self._next_client + k + 1) % len(self._clients)
                c.submit(sticks, arm)
                return
        self.skipped_busy += 1

    def _run(self) -> None:
        start = self.clock()
        next_t = start
        arm_until = start + ARM_GESTURE_S
        arm_give_up = start + ARM_GIVE_UP_S
        leg_end_sim = None
        while not self._stop.is_set():
            now = self.clock()
            if now < next_t:
                time.sleep(min(next_t - now, 0.005))
                continue
            next_t += COMMAND_PERIOD_S
            # Hold the arming gesture until the APM is armed (an operator watches the motors spin
            # up),
            # at least ARM_GESTURE_S: on a loaded machine simulated time may run slower than ours.
            if now < arm_until or (not self.rig.snapshot().armed and now < arm_give_up):
                self._send(ARM_STICKS_US, True)
                continue
            s = self.rig.snapshot()
            if leg_end_sim is None or (
                s.t_us >= leg_end_sim and self.leg_index < len(self.plan) - 1
            ):
                if leg_end_sim is not None:
                    self.leg_index += 1
                leg = self.plan[self.leg_index]
                self.leg_started_sim_us.append(s.t_us)
                leg_end_sim = s.t_us + int(leg.duration_s * 1e6)
            leg = self.plan[self.leg_index]
            if leg.land and s.landed:
                self._send(IDLE_STICKS_US, False)  # on the ground: disarm
                self.disarmed_sim_us = self.disarmed_sim_us or s.t_us
                continue
            self._send(sticks_for(s, leg.target_ned_m, leg.yaw_rad, leg.gains(PilotGains())), True)
