"""A ground station stand-in that talks to the craft the real way: signed `PUT /control` requests
over HTTP to the WiFi bridge at 50 Hz, sticks from the ground-truth pilot (position source: the
emulator's truth, where quad-control would use SLAM). Used where quad-control / slam-server are not
in the loop; the HTTP, MAC, sequence and reply handling are the protocol's (rgbd_protocol.control).

Runs on its own thread, paced by the wall clock passed in (it is a real-time client of the rig).
`kill()` stops it dead without a goodbye, as a crashed ground-station process would.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import http.client
import threading
import time

from hilrig.flight import Leg
from hilrig.pilot import ARM_STICKS_US, IDLE_STICKS_US, PilotGains, sticks_for

COMMAND_PERIOD_S = 0.02      # 50 Hz, the thesis' command rate (quad-control's period_ms)
ARM_GESTURE_S = 2.4          # ArduCopter's 2 s arming delay + margin for the PWM frame delay
# quad-control gives up after 100 ms; this stand-in waits 1 s so a loaded CI machine is not mistaken
# for a link fault (late replies are counted in round_trip_ms).
HTTP_TIMEOUT_S = 1.0


@dataclass
class GroundStationStats:
    sent: int = 0
    statuses: dict = field(default_factory=dict)
    round_trip_ms: list = field(default_factory=list)
    errors: int = 0


class GroundStation:
    def __init__(self, bridge_port: int, key: bytes, rig, plan: list[Leg], clock=time.monotonic) -> None:
        from rgbd_protocol.control import SequenceCounter

        self.port = bridge_port
        self.key = key
        self.rig = rig
        self.plan = plan
        self.clock = clock
        self.seqs = SequenceCounter()
        self.stats = GroundStationStats()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ground-station", daemon=True)
        self.leg_index = 0
        self.disarmed_sim_us: int | None = None
        self.leg_started_sim_us: list[int] = []

    def start(self) -> "GroundStation":
        self._thread.start()
        return self

    def kill(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def _put(self, conn: http.client.HTTPConnection, sticks, arm: bool) -> None:
        from rgbd_protocol.control import build_control_request

        line = build_control_request(self.key, self.seqs.next(), arm, *sticks)
        target = line.split(" ", 1)[1]
        t0 = self.clock()
        conn.request("PUT", target)
        r = conn.getresponse()
        r.read()
        self.stats.round_trip_ms.append((self.clock() - t0) * 1e3)
        self.stats.sent += 1
        self.stats.statuses[r.status] = self.stats.statuses.get(r.status, 0) + 1

    def _run(self) -> None:
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=HTTP_TIMEOUT_S)
        start = self.clock()
        next_t = start
        arm_until = start + ARM_GESTURE_S
        leg_end_sim = None
        while not self._stop.is_set():
            now = self.clock()
            if now < next_t:
                time.sleep(min(next_t - now, 0.005))
                continue
            next_t += COMMAND_PERIOD_S
            try:
                if now < arm_until:
                    self._put(conn, ARM_STICKS_US, True)
                    continue
                s = self.rig.snapshot()
                if leg_end_sim is None or (s.t_us >= leg_end_sim and self.leg_index < len(self.plan) - 1):
                    if leg_end_sim is not None:
                        self.leg_index += 1
                    leg = self.plan[self.leg_index]
                    self.leg_started_sim_us.append(s.t_us)
                    leg_end_sim = s.t_us + int(leg.duration_s * 1e6)
                leg = self.plan[self.leg_index]
                if leg.land and s.landed:
                    self._put(conn, IDLE_STICKS_US, False)  # on the ground: disarm
                    self.disarmed_sim_us = self.disarmed_sim_us or s.t_us
                    continue
                self._put(conn, sticks_for(s, leg.target_ned_m, leg.yaw_rad, leg.gains(PilotGains())), True)
            except (OSError, http.client.HTTPException):
                self.stats.errors += 1
                conn.close()
                conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=HTTP_TIMEOUT_S)
        conn.close()
