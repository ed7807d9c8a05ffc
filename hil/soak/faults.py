"""Injects the schedule's faults (soak.schedule) into a running closed-loop flight
(hilrig.slam_flight.SlamFlight), through the rig's existing fault mechanisms:

  stream_stall, stream_degraded   the stream links' LinkProxy (stall(), impairment)
  control_loss                    the control link's LinkProxy (impairment)
  control_back_to_back            LiveRig.back_to_back_extra (the bridge forwards bursts)
  slam_server_kill                SlamFlight.kill_slam_server / restart_slam_server
  ground_station_kill             SlamFlight.kill_ground_station
  camera_blank, camera_malformed  soak.kinect_faults.FaultyLiveKinect.inject
  cpu_burners                     stress-ng --cpu N (hilrig.procs.ManagedProcess: stopped by PID)
  gusts                           the airframe model's gust level (QuadParams.gust_accel_std_mss)

`FaultInjector` runs one mission's faults on its own thread, each at its time after the mission's
take-off command; ending a fault restores what it changed. `stop()` ends every active fault at once
(mission over, Ctrl-C) and stops every process it started, by PID.
"""

from __future__ import annotations

import dataclasses
import heapq
import threading
import time
from pathlib import Path

from hilrig.link_proxy import LinkImpairment
from hilrig.procs import ManagedProcess

from soak.schedule import Fault


class FaultInjector:
    def __init__(self, flight, base_gust_mss: float, workdir: Path, say=print) -> None:
        self.flight = flight
        self.base_gust_mss = base_gust_mss
        self.workdir = Path(workdir)
        self.say = say
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._burners: dict[int, ManagedProcess] = {}
        self.injected: list[dict] = []  # one per fault started: id, kind, mission time, wall time
        self.errors: list[str] = []
        self.ground_station_killed_at: float | None = None  # time.monotonic()
        self.ground_station_killed_sim_us: int | None = None
        self.slam_server_restarts = 0
        # Active windows by kind: how many are on (overlapping faults of one kind nest).
        self._active: dict[str, int] = {}
        self.control_fault_windows: list[tuple[float, float]] = []  # monotonic s, for outcomes

    # ---- life cycle -----------------------------------------------------------------------------
    def run_mission(self, faults: tuple, takeoff_mono_s: float) -> None:
        """Starts a thread that injects `faults` at takeoff_mono_s + at_s and ends each after its
        duration."""
        self._stop.clear()
        self._thread = threading.Thread(
            target=self._run, args=(list(faults), takeoff_mono_s), name="soak-faults", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        """Ends every active fault now and waits for the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=30)
            self._thread = None
        self._end_all()

    # ---- thread ---------------------------------------------------------------------------------
    def _run(self, faults: list[Fault], t0: float) -> None:
        events: list[tuple[float, int, str, Fault]] = []
        for n, f in enumerate(faults):
            heapq.heappush(events, (t0 + f.at_s, n, "start", f))
        while events and not self._stop.is_set():
            due, n, what, f = events[0]
            wait = due - time.monotonic()
            if wait > 0:
                self._stop.wait(min(wait, 0.05))
                continue
            heapq.heappop(events)
            try:
                if what == "start":
                    self._start(f, t0)
                    if f.duration_s > 0 and f.kind != "ground_station_kill":
                        heapq.heappush(events, (due + f.duration_s, n, "end", f))
                else:
                    self._end(f)
            except Exception as e:  # noqa: BLE001 - a fault that cannot be applied is a finding
                self.errors.append(f"{f.fault_id} {what}: {e!r}")
                self.say(f"soak: fault {f.fault_id} {what} failed: {e!r}")
            if f.kind == "ground_station_kill" and what == "start":
                break  # the mission ends; nothing after it is injected

    # ---- faults ---------------------------------------------------------------------------------
    def _start(self, f: Fault, t0: float) -> None:
        fl = self.flight
        now = time.monotonic()
        p = f.params
        self.injected.append(
            {
                "fault": f.fault_id,
                "kind": f.kind,
                "mission_s": round(now - t0, 2),
                "sim_s": round(fl.rig.sim_us / 1e6, 2),
                "duration_s": f.duration_s,
                "params": p,
            }
        )
        self.say(
            f"soak:   fault {f.kind} {p or ''} for {f.duration_s:.1f} s (mission +{now - t0:.0f} s)"
        )
        with self._lock:
            self._active[f.kind] = self._active.get(f.kind, 0) + 1
        if f.kind == "stream_stall":
            for proxy in fl.stream_proxies:
                proxy.stall(f.duration_s)
        elif f.kind == "stream_degraded":
            imp = LinkImpairment(
                delay_ms=p["delay_ms"], jitter_ms=p["jitter_ms"], loss=p["loss"], seed=f.mission
            )
            for proxy in fl.stream_proxies:
                proxy.impairment = imp
        elif f.kind == "control_loss":
            fl.control_proxy.impairment = LinkImpairment(
                delay_ms=p["delay_ms"], loss=p["loss"], seed=f.mission
            )
            self.control_fault_windows.append((now, now + f.duration_s))
        elif f.kind == "control_back_to_back":
            fl.rig.back_to_back_extra = int(p["extra_lines"])
        elif f.kind == "slam_server_kill":
            fl.kill_slam_server()
        elif f.kind == "ground_station_kill":
            self.ground_station_killed_at = now
            self.ground_station_killed_sim_us = fl.rig.sim_us
            fl.kill_ground_station()
        elif f.kind in ("camera_blank", "camera_malformed"):
            fl.kinect.inject(f.kind.split("_", 1)[1], now, int(p["frames"]))
        elif f.kind == "cpu_burners":
            from hilrig.realtime import normal_policy_argv

            argv = ["stress-ng", "--cpu", str(int(p["workers"])), "--cpu-method", "matrixprod"]
            proc = ManagedProcess(
                normal_policy_argv(argv),
                self.workdir / f"stress-ng-{f.mission}-{len(self.injected)}.log",
            )
            with self._lock:
                self._burners[id(f)] = proc
        elif f.kind == "gusts":
            self._set_gust(p["gust_accel_std_mss"])
        else:
            raise ValueError(f"unknown fault kind {f.kind!r}")

    def _end(self, f: Fault) -> None:
        fl = self.flight
        with self._lock:
            left = self._active.get(f.kind, 0) - 1
            self._active[f.kind] = max(0, left)
        if f.kind == "slam_server_kill":
            fl.restart_slam_server()
            self.slam_server_restarts += 1
            return
        if f.kind == "cpu_burners":
            with self._lock:
                proc = self._burners.pop(id(f), None)
            if proc is not None:
                proc.stop()
            return
        if left > 0:
            return  # another fault of this kind is still on: it decides when to clear
        if f.kind == "stream_degraded":
            for proxy in fl.stream_proxies:
                proxy.impairment = LinkImpairment()
        elif f.kind == "control_loss":
            fl.control_proxy.impairment = LinkImpairment()
        elif f.kind == "control_back_to_back":
            fl.rig.back_to_back_extra = 0
        elif f.kind == "gusts":
            self._set_gust(self.base_gust_mss)

    def _end_all(self) -> None:
        fl = self.flight
        with self._lock:
            burners, self._burners = list(self._burners.values()), {}
            self._active.clear()
        for proc in burners:
            proc.stop()
        for proxy in fl.stream_proxies:
            proxy.impairment = LinkImpairment()
        if fl.control_proxy is not None:
            fl.control_proxy.impairment = LinkImpairment()
        if fl.rig is not None:
            fl.rig.back_to_back_extra = 0
            self._set_gust(self.base_gust_mss)
        # A slam-server killed by a fault whose end (the restart) did not come: restart it now.
        if "slam-server" in fl._killed_on_purpose:
            fl.restart_slam_server()
            self.slam_server_restarts += 1

    def _set_gust(self, level_mss: float) -> None:
        model = self.flight.rig.fc.model
        # QuadParams is frozen: a new one, swapped in whole (the model reads it once per step).
        model.params = dataclasses.replace(model.params, gust_accel_std_mss=float(level_mss))

    def burner_pids(self) -> list[int]:
        with self._lock:
            return [p.pid for p in self._burners.values()]
