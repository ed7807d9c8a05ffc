"""A firmware double for the dashboard tests: the ATmega side of the control link in Python.

It answers the serial-link lines of protocol/control (`PUT /control?...&mac=..` and `GET /status`)
using rgbd_protocol.control (MAC, field order, ranges and reply fields come from the spec), with
the behaviour the browser tests need: MAC check (401), replay check (409), arming state, a fake
attitude reading. It is fronted by the WiFi-bridge emulator (rgbd_protocol.control_bridge), so
quad-control talks HTTP to it exactly as to the real bridge. Not the real firmware: the simavr
harness (hil/arduino, hilrig.LiveRig) can replace it through the same `transact` callable.
Thread-safe (one lock).
"""

from __future__ import annotations

import json
import threading
import time

from rgbd_protocol import control

FW_VERSION = "double-0.1"


class FirmwareDouble:
    def __init__(self, key: bytes) -> None:
        self._key = key
        self._lock = threading.Lock()
        self.state = "disarmed"
        self.seq = 0
        self.out_us = [1500, 1500, 1000, 1500]  # ArduPilot order roll, pitch, throttle, yaw
        self.accepted: list[dict] = []
        self.rejected: dict[int, int] = {}
        self._start = time.monotonic()

    def _reply(self, status: int) -> str:
        age = int((time.monotonic() - self._start) * 1000) % 20  # a reading every 20 ms
        obj = {
            "ver": control.CONTROL_LINK_VERSION,
            "err": control.STATUS_REASONS[status],
            "fw": FW_VERSION,
            "state": self.state,
            "seq": self.seq,
            "out_us": list(self.out_us),
            "clamped": 0,
            "att_mrad": [12, -34, 1571],
            "att_age_ms": age,
            "imu_raw": [1, -2, -1000, 30, -40, 5],
            "imu_age_ms": age,
        }
        assert list(obj) == control.REPLY_FIELDS
        return f"{status} {json.dumps(obj, separators=(',', ':'))}"

    def _reject(self, status: int) -> str:
        self.rejected[status] = self.rejected.get(status, 0) + 1
        return self._reply(status)

    def transact(self, line: str, timeout_s: float) -> str | None:
        del timeout_s
        with self._lock:
            if line == control.build_status_request():
                return self._reply(200)
            prefix = f"PUT {control.CONTROL_PATH}?"
            if not line.startswith(prefix):
                return self._reject(404 if line.startswith("PUT ") else 400)
            try:
                pairs = [p.split("=", 1) for p in line[len(prefix) :].split("&")]
                names = [p[0] for p in pairs]
                if names != control.FIELDS + ["mac"]:
                    return self._reject(400)
                v = {k: int(x) for k, x in pairs[:-1]}
                expected = control.build_control_request(
                    self._key, v["seq"], bool(v["arm"]), v["roll"], v["pitch"], v["thr"], v["yaw"]
                )
            except ValueError:
                return self._reject(422)
            if expected != line:
                return self._reject(401)
            if v["seq"] <= self.seq:
                return self._reject(409)
            self.seq = v["seq"]
            self.state = "armed" if v["arm"] else "disarmed"
            self.out_us = (
                [v["roll"], v["pitch"], v["thr"], v["yaw"]]
                if v["arm"]
                else [1500, 1500, 1000, 1500]
            )
            self.accepted.append(v)
            return self._reply(200)

    def last_command(self) -> dict | None:
        with self._lock:
            return dict(self.accepted[-1]) if self.accepted else None
