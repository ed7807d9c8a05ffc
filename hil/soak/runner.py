"""`make soak`: closed-loop HIL missions flown back to back for SOAK_MINUTES with the seeded fault
schedule of soak.schedule, then a report (soak.report) and the replay check (soak.replay_check).

    PYTHONPATH=protocol/python:offboard/recorder:hil .venv/bin/python -m soak.runner \
        [--minutes 60] [--seed N] [--out out/soak] [--no-replay]

One SlamFlight (hilrig.slam_flight) runs for the whole soak: the rig (firmware in simavr, FC
emulator, Kinect emulator), rgbd-streamer and slam-server live through every mission, so their
memory and descriptors are watched over the run. quad-control is started for each mission (the
operator starts the ground station, flies, lands), which gives each mission its own flight log and
MCAP recording and is also how a mission after a ground-station kill begins.

A mission: wait for tracking and the floor, arm, take off to 1.7 m, hold 8 s (scored after 5 s of
settling), fly the box of four waypoints of the long flight (1 m x 0.8 m, ending over the pad),
two turns in place (+-90 deg, 5 s holds), land. The pad is where the first mission took off; the
operator clicks the box relative to it, so the craft does not walk across the room over an hour.

Outcome of a mission, from the emulator's truth only (never from what quad-control says):
soak.outcome (completed / landed by failsafe as expected / aborted (landed safely) / lost).
Ctrl-C (or SIGTERM): the current mission stops, every process the soak started is stopped by its
PID, and the report covers the missions flown so far.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import signal
import sys
import time
import traceback
from pathlib import Path

import numpy as np

# Missions fly the closed-loop scenarios' disturbances as the base level (gusts change under the
# `gusts` fault): 0.15 m/s^2, 2 s correlation, 0.5 / -0.3 deg trim error (docs/hil.md).
BASE_GUST_MSS = 0.15
HOLD_S = 8.0
TURN_HOLD_S = 5.0
# The long flight's box, relative to the pad (m, floor frame at the first take-off): the two
# waypoints of scenario 2 and the way back.
BOX = ((1.0, 0.0), (1.0, 0.8), (0.0, 0.8), (0.0, 0.0))
# After a mission gives up or a ground-station kill: the APM's LAND from 1.7 m at 0.5 m/s takes
# ~4 s, plus the 500 ms radio-failsafe delay and the 1 s land detector.
LANDING_WAIT_S = 60.0
# Between missions the operator carries a craft that landed more than this far from the pad (or
# turned more than PAD_YAW_TOLERANCE_DEG) back onto it, as one does between flights: failsafe
# landings drift 0.6-1.5 m each in the gusts, and a first soak without this walked the craft into
# the room's wall in 12 missions (the camera then renders nothing and every later mission fails).
PAD_TOLERANCE_M = 0.3
PAD_YAW_TOLERANCE_DEG = 10.0
# Before each step (waypoint, turn, land) the operator waits for the craft to hold: a step given
# in quad-control's lost-hold is refused (waypoint, turn) or lands blind (land), where an operator
# would wait the few seconds a lost-hold lasts. quad-control's lost-hold is 2 s after 300 ms
# without a pose, then it lands blind itself; 5 s covers that with the reconnect and relocalisation
# of a restarted slam-server and the first hold-state poll after it.
WAIT_FOR_HOLD_S = 5.0
# Resource samples of every process (RSS, open descriptors) this often.
SAMPLE_PERIOD_S = 10.0
# Recordings of missions that went as expected are deleted but for the first few completed ones
# (the check replays three of them); those of every other mission are kept. A mission records
# ~1 GB (two 512 MB files), so an hour would fill ~30 GB.
KEEP_EXPECTED_RECORDINGS = 5


def _say(text: str) -> None:
    print(text, flush=True)


class Interrupted(Exception):
    pass


def _on_signal(signum, frame):  # noqa: ARG001
    raise KeyboardInterrupt


def room_from_floor(
    origin_room: np.ndarray, yaw_room_rad: float, x_m: float, y_m: float, z_m: float
) -> np.ndarray:
    """A point of quad-control's floor frame (x forward, y left at its start, origin under the
    camera) in the room frame, for a floor frame whose x axis points `yaw_room_rad`
    counter-clockwise from the room's x axis."""
    c, s = math.cos(yaw_room_rad), math.sin(yaw_room_rad)
    return np.array([origin_room[0] + c * x_m - s * y_m, origin_room[1] + s * x_m + c * y_m, z_m])


def floor_from_room(origin_room: np.ndarray, yaw_room_rad: float, p_room) -> tuple[float, float]:
    dx, dy = p_room[0] - origin_room[0], p_room[1] - origin_room[1]
    c, s = math.cos(yaw_room_rad), math.sin(yaw_room_rad)
    return (round(c * dx + s * dy, 3), round(-s * dx + c * dy, 3))


class Soak:
    def __init__(self, seed: int, minutes: float, out_dir: Path, replay: bool = True) -> None:
        from soak.schedule import make_schedule

        self.seed = seed
        self.minutes = minutes
        self.out = Path(out_dir)
        self.replay = replay
        self.schedule = make_schedule(seed, minutes)
        self.missions: list[dict] = []
        self.exits: list[dict] = []
        self.samples: dict[str, list] = {}  # "name pid" -> [(elapsed_s, rss_kb, fds)]
        self.flight = None
        self.injector = None
        self.pad_room: np.ndarray | None = None
        self.pad_ned: tuple | None = None  # (position NED m, yaw rad) of the craft at the pad
        self.t_start = 0.0
        self.interrupted = False
        self.expected_recordings_kept = 0
        self.segments = 0
        self.fatal: str | None = None

    # ---- the run --------------------------------------------------------------------------------
    def run(self) -> int:
        from soak import report

        self.out.mkdir(parents=True, exist_ok=True)
        (self.out / "schedule.json").write_text(json.dumps(self.schedule.to_dict(), indent=1))
        self.t_start = time.monotonic()
        deadline = self.t_start + self.minutes * 60.0
        _say(
            f"soak: seed {self.seed}, {self.minutes:g} min, {len(self.schedule.missions)} missions "
            f"planned, out {self.out}"
        )
        try:
            for plan in self.schedule.missions:
                if time.monotonic() >= deadline:
                    break
                if self.flight is None:
                    self._start_flight()
                self._fly(plan, deadline)
        except KeyboardInterrupt:
            self.interrupted = True
            if self.missions and "outcome" not in self.missions[-1]:
                self.missions[-1]["outcome"] = "interrupted"
                self.missions[-1]["reason"] = "Ctrl-C during the mission (not judged)"
            _say("soak: interrupted: stopping every process it started (by PID)")
        except Exception as e:  # noqa: BLE001 - the report must still be written
            self.fatal = f"{e!r}\n{traceback.format_exc()[-3000:]}"
            _say(f"soak: stopped by an error: {e!r}")
        finally:
            self._stop_flight()
        replays = None
        if self.replay and not self.interrupted:
            from soak.replay_check import replay_missions

            replays = replay_missions(self.missions, self.out / "replay", say=_say)
        rep = report.build(self, replays)
        report.write(rep, self.out)
        _say(report.text(rep))
        _say(f"soak: report {self.out / 'report.json'}, {self.out / 'report.txt'}")
        return 0 if rep["summary"]["ok"] else 1

    def elapsed_s(self) -> float:
        return time.monotonic() - self.t_start

    def _start_flight(self) -> None:
        from fc_emulator import QuadParams
        from hilrig.link_proxy import LinkImpairment
        from hilrig.slam_flight import SlamFlight, SlamFlightOptions

        from soak.faults import FaultInjector
        from soak.kinect_faults import FaultyLiveKinect
        from soak.sampler import ResourceSampler

        self.segments += 1
        workdir = self.out / f"flight-{self.segments}"
        if workdir.exists():
            shutil.rmtree(workdir)
        options = SlamFlightOptions(
            quad_params=QuadParams(
                gust_accel_std_mss=BASE_GUST_MSS,
                gust_tau_s=2.0,
                trim_error_deg=(0.5, -0.3),
                disturbance_seed=self.seed % 2**31,
            ),
            # Proxies on both links from the start (no impairment until a fault sets one).
            stream_impairment=LinkImpairment(),
            control_impairment=LinkImpairment(),
            # The shipped streamer configuration over WiFi (docs/recording.md): JPEG + RVL.
            rgb_encoding="jpeg",
            kinect_factory=FaultyLiveKinect,
        )
        _say(f"soak: starting the rig, slam-server, rgbd-streamer ({workdir})")
        self.flight = SlamFlight(workdir, options).start()
        self.injector = FaultInjector(self.flight, BASE_GUST_MSS, workdir, say=_say)
        self.sampler = ResourceSampler(self._pids, SAMPLE_PERIOD_S, self.samples, self.t_start)
        self.sampler.start()
        self.pad_room = None

    def _pids(self) -> dict[str, int]:
        out = {}
        if self.flight is not None:
            out.update(self.flight.process_ids())
        if self.injector is not None:
            for n, pid in enumerate(self.injector.burner_pids()):
                out[f"stress-ng-{n}"] = pid
        out["soak-runner"] = os.getpid()
        return out

    def _stop_flight(self) -> None:
        if self.injector is not None:
            try:
                self.injector.stop()
            except Exception as e:  # noqa: BLE001
                _say(f"soak: ending faults failed: {e!r}")
        if getattr(self, "sampler", None) is not None:
            self.sampler.stop()
        if self.flight is not None:
            self._note_exits(mission=None)
            try:
                self.flight.close()
            except Exception as e:  # noqa: BLE001 - a rig that failed is reported, not raised
                self.exits.append({"process": "rig", "mission": None, "error": repr(e)})
            self.flight = None
            self.injector = None

    def _note_exits(self, mission) -> None:
        """Processes that exited without the soak killing them (quad-control is judged by the
        mission: its kill is a fault)."""
        fl = self.flight
        for name, p in fl._procs:
            if p.alive() or name in fl._killed_on_purpose or getattr(p, "_soak_noted", False):
                continue
            if name == "quad-control" and (
                self.injector.ground_station_killed_at is not None or p.proc.returncode == -9
            ):
                continue
            p._soak_noted = True
            self.exits.append(
                {
                    "process": name,
                    "pid": p.pid,
                    "mission": mission,
                    "exit_code": p.proc.returncode,
                    "log_tail": p.log_text()[-800:],
                }
            )
            _say(f"soak: UNEXPECTED EXIT {name} (pid {p.pid}, code {p.proc.returncode})")

    # ---- one mission ----------------------------------------------------------------------------
    def _fly(self, plan, deadline: float) -> None:
        from hilrig import missions
        from hilrig.slam_flight import camera_room_position

        fl = self.flight
        n = plan.index
        mdir = self.out / "missions" / f"mission-{n:03d}"
        mdir.mkdir(parents=True, exist_ok=True)
        rec = {
            "mission": n,
            "seed": self.seed,
            "planned_faults": [f.fault_id for f in plan.faults],
            "started_elapsed_s": round(self.elapsed_s(), 1),
            "dir": str(mdir),
            "segment": self.segments,
            "steps": [],
        }
        self.missions.append(rec)
        left = max(0.0, deadline - time.monotonic())
        _say(
            f"soak: mission {n}: start (elapsed {self.elapsed_s() / 60:.1f} min, remaining "
            f"{left / 60:.1f} min, {len(plan.faults)} faults planned)"
        )
        inj = self.injector
        inj.injected, inj.errors = [], []
        inj.ground_station_killed_at = inj.ground_station_killed_sim_us = None
        inj.control_fault_windows = []
        self._carry_to_pad(rec)
        # The previous missions are scored: what the rig and the Kinect emulator kept of them is
        # dropped, so the runner's memory does not grow with the soak's length.
        fl.rig.forget_before(fl.rig.sim_us)
        fl.kinect.forget_before(time.monotonic())
        maps_before = self._slam_maps()
        fl.restart_ground_station(mdir / "flight-log", mdir / "recording")
        events_before = len(fl.rig.fc.events)
        touch_before = len(fl.rig.fc.touchdowns_mps)
        sim_start = fl.rig.sim_us
        start_snap = fl.rig.snapshot()
        origin = camera_room_position(start_snap, fl.options.mount)
        yaw_room = -float(start_snap.yaw_rad)  # NED yaw is clockwise; the room's is counter-
        if self.pad_room is None:
            self.pad_room = origin.copy()
        goals_room = [origin + np.array([0, 0, missions.HOLD_HEIGHT_M])]
        try:
            self._take_off(fl, rec, plan)
            rec["steps"].append("take-off")
            rec["hold"] = missions.hold(fl, origin, HOLD_S)
            rec["steps"].append("hold")
            rec["waypoints"] = []
            for bx, by in BOX:
                self._wait_for_hold(fl)
                # The box is drawn in the pad's frame (room axes), clicked in the floor frame.
                p_room = self.pad_room + np.array([bx, by, 0.0])
                x, y = floor_from_room(origin, yaw_room, p_room)
                goal = room_from_floor(origin, yaw_room, x, y, missions.HOLD_HEIGHT_M)
                goals_room.append(goal)
                rec["waypoints"].append(self._go_to(fl, goal, x, y))
                rec["steps"].append(f"waypoint {bx:g},{by:g}")
            for yaw in plan.turns_ccw_deg:
                self._wait_for_hold(fl)
                rec.setdefault("turns", []).append(
                    missions.turn(
                        fl,
                        goals_room[-1] - np.array([0, 0, missions.HOLD_HEIGHT_M]),
                        yaw,
                        TURN_HOLD_S,
                    )
                )
                rec["steps"].append(f"turn {yaw:+.0f}")
            self._wait_for_hold(fl)
            rec["landing"] = missions.land(fl)
            rec["steps"].append("landed")
            rec["completed_steps"] = True
        except KeyboardInterrupt:
            raise
        except Exception as e:  # noqa: BLE001 - a mission that could not go on is judged by truth
            rec["completed_steps"] = False
            rec["gave_up"] = f"{type(e).__name__}: {str(e)[:400]}"
            last = rec["steps"][-1] if rec["steps"] else "start"
            _say(f"soak: mission {n}: stopped after '{last}': {rec['gave_up'][:200]}")
        finally:
            inj.stop()
            rec["faults_injected"] = list(inj.injected)
            rec["fault_errors"] = list(inj.errors)
        if not rec["completed_steps"]:
            self._bring_down(rec)
        self._judge(rec, events_before, touch_before, sim_start, goals_room)
        self._scores(rec, mdir)
        # The SLAM maps slam-server began for this mission (one, unless it was restarted): their
        # tables and lock schedules let the replay check hold the replay to the flight's order.
        rec["slam_maps"] = sorted(str(p) for p in self._slam_maps() - maps_before)
        self._note_exits(mission=n)
        self._prune_recording(rec, mdir)
        (mdir / "mission.json").write_text(json.dumps(rec, indent=1, default=str))
        kinds = ", ".join(f["kind"] for f in rec["faults_injected"]) or "none"
        _say(
            f"soak: mission {n}: {rec['outcome'].upper()} ({rec.get('reason', '')}) "
            f"faults: {kinds}; "
            f"elapsed {self.elapsed_s() / 60:.1f} min, remaining "
            f"{max(0.0, deadline - time.monotonic()) / 60:.1f} min"
        )

    def _slam_maps(self) -> set[Path]:
        """slam-server's map folders so far (--tables-dir: slam-tables*/map-*)."""
        return set(self.flight.workdir.glob("slam-tables*/map-*"))

    def _carry_to_pad(self, rec: dict) -> None:
        """The operator puts a landed craft back on the pad (the airframe model's position, heading
        and rates are set; the rig thread may be stepping it, so the move is checked and repeated).
        Done before quad-control starts, so its floor frame is the pad's."""
        fl = self.flight
        snap = fl.rig.snapshot()
        if self.pad_ned is None:
            self.pad_ned = (np.array(snap.pos_ned_m, float), float(snap.yaw_rad))
            return
        if snap.armed or not snap.landed:
            rec["carried_to_pad"] = "not possible: the craft is not landed and disarmed"
            return
        pad, pad_yaw = self.pad_ned
        off_m = float(np.hypot(*(np.array(snap.pos_ned_m[:2]) - pad[:2])))
        off_deg = abs(math.degrees((snap.yaw_rad - pad_yaw + math.pi) % (2 * math.pi) - math.pi))
        if off_m <= PAD_TOLERANCE_M and off_deg <= PAD_YAW_TOLERANCE_DEG:
            return
        state = fl.rig.fc.model.state
        for _ in range(10):
            state.pos_ned_m = np.array([pad[0], pad[1], state.pos_ned_m[2]])
            state.vel_ned_mps = np.zeros(3)
            state.rate_body_rad_s = np.zeros(3)
            state.yaw_rad = pad_yaw
            time.sleep(0.2)
            now = fl.rig.snapshot()
            if float(np.hypot(*(np.array(now.pos_ned_m[:2]) - pad[:2]))) < 0.01:
                break
        rec["carried_to_pad"] = {"from_m": round(off_m, 2), "turned_deg": round(off_deg, 1)}
        _say(f"soak: mission {rec['mission']}: craft carried back to the pad ({off_m:.2f} m)")

    def _take_off(self, fl, rec: dict, plan) -> None:
        """missions.take_off, with the mission's faults started at the take-off command (their
        times count from it)."""
        fl.wait_until(
            lambda s: s.get("tracking") and (s["floor"]["found"] or s["floor"]["fallback"]),
            timeout_s=90,
            what="tracking + floor",
        )
        fl.command("arm")
        fl.wait_until(
            lambda s: s["state"] == "armed"
            and s["command"]["yaw_pct"] == 0.0
            and fl.rig.snapshot().armed,
            timeout_s=20,
            what="armed (gesture finished)",
        )
        end = time.monotonic() + 20.0
        while True:
            try:
                fl.command("takeoff")
                break
            except RuntimeError as e:
                if "no tracked pose" not in str(e) or time.monotonic() > end:
                    raise
                time.sleep(0.2)
        rec["takeoff_sim_s"] = round(fl.rig.sim_us / 1e6, 2)
        self.injector.run_mission(plan.faults, time.monotonic())
        fl.wait_until(lambda s: s["state"] == "hold", timeout_s=60, what="take-off -> hold")
        rec["hold_reached_s"] = round(fl.rig.sim_us / 1e6 - rec["takeoff_sim_s"], 1)

    @staticmethod
    def _wait_for_hold(fl) -> None:
        """What an operator does before the next click: waits while quad-control is in lost-hold
        (the step would be refused or land blind). Any other state is left to the step."""
        fl.wait_until(
            lambda s: s["state"] != "lost-hold",
            timeout_s=WAIT_FOR_HOLD_S,
            what="the craft out of lost-hold",
        )

    def _go_to(self, fl, goal_room: np.ndarray, x_m: float, y_m: float) -> dict:
        """missions.go_to with the goal in the room frame given (quad-control's floor frame is not
        the room's when the craft started turned)."""
        from hilrig import missions
        from hilrig.slam_flight import hold_error

        fl.waypoint(x_m, y_m)
        fl.wait_until(lambda s: s["state"] == "go-to-waypoint", timeout_s=5, what="go-to-waypoint")
        t_start = fl.rig.sim_us
        fl.wait_until(
            lambda s: s["state"] == "hold"
            and ("waypoint reached" in s["last_event"] or missions._setpoint_at(s, x_m, y_m)),
            timeout_s=60,
            what=f"arrival at ({x_m}, {y_m})",
        )
        t_arrived = fl.rig.sim_us
        fl.hold_for(missions.ARRIVAL_SETTLE_S)
        t_end = fl.rig.sim_us
        err = hold_error(fl.rig.history(), goal_room, fl.options.mount, t_end - 1e6, t_end)
        return {"floor_xy_m": [x_m, y_m], "leg_s": round((t_arrived - t_start) / 1e6, 1), **err}

    def _bring_down(self, rec: dict) -> None:
        """After a mission gave up: a craft still flying is landed (quad-control's land if it
        lives, else its kill: the firmware failsafe lands); waits for the truth to say disarmed."""
        fl = self.flight
        if not fl.rig.snapshot().armed:
            return
        try:
            fl.command("land")
            rec["bring_down"] = "quad-control land"
        except Exception:  # noqa: BLE001 - quad-control dead or refusing
            fl.kill_ground_station()
            rec["bring_down"] = "quad-control killed (firmware failsafe)"
        end = time.monotonic() + LANDING_WAIT_S
        while time.monotonic() < end and fl.rig.snapshot().armed:
            time.sleep(0.5)
        if fl.rig.snapshot().armed:
            # A craft that will not come down: the ground station goes, the failsafe must act.
            fl.kill_ground_station()
            rec["bring_down"] += "; then quad-control killed"
            end = time.monotonic() + LANDING_WAIT_S
            while time.monotonic() < end and fl.rig.snapshot().armed:
                time.sleep(0.5)

    def _judge(self, rec, events_before, touch_before, sim_start, goals_room) -> None:
        """The outcome, from the emulator's truth only."""
        from hilrig.slam_flight import camera_room_position

        from soak.outcome import judge

        fl = self.flight
        inj = self.injector
        if inj.ground_station_killed_at is not None:
            # The kill ends the mission: wait for the failsafe landing.
            end = time.monotonic() + LANDING_WAIT_S
            while time.monotonic() < end and fl.rig.snapshot().armed:
                time.sleep(0.5)
            time.sleep(1.0)
        snap = fl.rig.snapshot()
        events = [(t, e) for t, e in list(fl.rig.fc.events)[events_before:]]
        failsafes = [(t, e) for t, e in events if "failsafe" in e]
        touchdowns = list(fl.rig.fc.touchdowns_mps)[touch_before:]
        hist = [h for h in fl.rig.history() if h.t_us >= sim_start][::20]
        mount = fl.options.mount
        pos = np.array([camera_room_position(h, mount) for h in hist]) if hist else np.zeros((0, 3))
        goals = np.array(goals_room)
        dist = (
            np.min(
                np.hypot(pos[:, None, 0] - goals[None, :, 0], pos[:, None, 1] - goals[None, :, 1]),
                axis=1,
            )
            if len(pos)
            else np.zeros(0)
        )
        far = float(np.max(dist)) if len(dist) else 0.0
        # Up to the first radio failsafe after the take-off command, the craft flew on
        # quad-control's commands; after it, the APM's LAND with no position source
        # (docs/failsafe.md).
        takeoff_us = (rec.get("takeoff_sim_s") or float("inf")) * 1e6
        failsafe_us = min(
            (t for t, e in failsafes if "cleared" not in e and t >= takeoff_us), default=None
        )
        t_hist = np.array([h.t_us for h in hist], dtype=float)
        under_control = dist if failsafe_us is None else dist[t_hist < failsafe_us]
        far_control = float(np.max(under_control)) if len(under_control) else 0.0
        rec["truth"] = {
            "armed_at_end": bool(snap.armed),
            "landed_at_end": bool(snap.landed),
            "failsafe_events": [f"{t / 1e6:.2f} s {e}" for t, e in failsafes],
            "touchdowns_mps": [round(v, 3) for v in touchdowns],
            "max_distance_from_path_m": round(far, 3),
            "max_distance_under_control_m": round(far_control, 3),
        }
        rec["outcome"], rec["reason"] = judge(
            rec["truth"],
            rec["completed_steps"],
            rec["faults_injected"],
            rec.get("takeoff_sim_s"),
            (rec.get("landing") or {}).get("t_land_sim_s"),
            rec.get("gave_up", ""),
        )

    def _scores(self, rec: dict, mdir: Path) -> None:
        """ATE, camera -> PWM latency, SLAM maps of the mission (quad-control's log and flight
        log; the soak's outcome never depends on them)."""
        from hilrig.verdict import map_resets

        fl = self.flight
        try:
            rec["ate"] = fl.ate()
        except Exception as e:  # noqa: BLE001
            rec["ate"] = {"error": repr(e)}
        try:
            lat = fl.latency()
            rec["capture_to_pwm_ms"] = lat.get("capture_to_pwm")
            rec["latency_frames"] = lat.get("frames")
        except Exception as e:  # noqa: BLE001
            rec["capture_to_pwm_ms"] = {"error": repr(e)}
        qc_log = mdir / "quad-control.log"
        text = qc_log.read_text(errors="replace") if qc_log.exists() else ""
        slam_log = fl.workdir / "slam-server.log"
        resets = map_resets(None, text, None)
        rec["slam"] = {
            "new_maps_after_first": resets["resets"],
            "link_breaks": resets["link_breaks"],
            "resumed": len(re.findall(r"map [0-9a-f]+ resumed \(world frame kept", text)),
            "disconnect_causes": resets["disconnect_causes"],
            "slam_server_restarts": sum(
                1 for f in rec["faults_injected"] if f["kind"] == "slam_server_kill"
            ),
            "slam_server_log": str(slam_log),
        }
        rec["recording"] = sorted(str(p) for p in (mdir / "recording").glob("*.mcap"))
        rec["realtime_factor"] = round(fl.rig.realtime_factor, 3)
        rec["load_average"] = Path("/proc/loadavg").read_text().split()[:3]
        rec["ended_elapsed_s"] = round(self.elapsed_s(), 1)

    def _prune_recording(self, rec: dict, mdir: Path) -> None:
        """Recordings of failures are kept, and those of the first completed missions (the replay
        check's); the rest are deleted."""
        if rec["outcome"] not in ("completed", "landed by failsafe as expected"):
            return
        if (
            rec["outcome"] == "completed"
            and self.expected_recordings_kept < KEEP_EXPECTED_RECORDINGS
        ):
            self.expected_recordings_kept += 1
            return
        shutil.rmtree(mdir / "recording", ignore_errors=True)
        rec["recording_deleted"] = rec["recording"]
        rec["recording"] = []


def main(argv=None) -> int:
    from soak.schedule import DEFAULT_SEED

    env = {}
    for name, kind in (("SOAK_MINUTES", float), ("SOAK_SEED", int)):
        value = os.environ.get(name, "").strip()
        if value:
            try:
                env[name] = kind(value)
            except ValueError:
                print(f"soak: {name} must be a number, not {value!r}", file=sys.stderr)
                return 2
    ap = argparse.ArgumentParser(
        prog="soak.runner",
        description="HIL missions back to back with a seeded schedule of faults, then a report "
        "(JSON + text) and a replay check of three missions' recordings.",
    )
    ap.add_argument(
        "--minutes",
        type=float,
        default=env.get("SOAK_MINUTES", 60.0),
        help="how long to fly missions (default: SOAK_MINUTES or 60)",
    )
    ap.add_argument(
        "--seed",
        type=int,
        default=env.get("SOAK_SEED", DEFAULT_SEED),
        help=f"schedule seed (default: SOAK_SEED or {DEFAULT_SEED})",
    )
    ap.add_argument(
        "--out", type=Path, default=Path("out/soak"), help="report folder (default out/soak)"
    )
    ap.add_argument("--no-replay", action="store_true", help="skip the replay check")
    try:
        args = ap.parse_args(argv)
    except SystemExit as e:
        return int(e.code or 0)
    if not (math.isfinite(args.minutes) and args.minutes > 0):
        print("soak: --minutes must be a positive number", file=sys.stderr)
        return 2
    from hilrig.slam_flight import missing_load_tool, missing_parts

    missing = missing_parts() + missing_load_tool()
    if missing:
        print("soak: cannot fly, not built / not installed: " + ", ".join(missing), file=sys.stderr)
        return 3
    signal.signal(signal.SIGTERM, _on_signal)
    return Soak(args.seed, args.minutes, args.out, replay=not args.no_replay).run()


if __name__ == "__main__":
    raise SystemExit(main())
