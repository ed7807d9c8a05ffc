"""Closed-loop flight with SLAM in the loop: every board is its emulator, every program the real
one.

    FC emulator (truth) --camera pose at each frame time--> LiveKinect (renders in a child process)
      --fakenect dump, FIFO index--> fakenect + rgbd-streamer (real, through the libfreenect API)
      --RGB/depth over TCP--> quad-control (real) --SLAM link--> slam-server (real) --pose-->
      quad-control's PID --signed HTTP PUT--> WiFi-bridge emulator --serial line--> firmware .elf in
      simavr (lock-step with the FC emulator, hilrig.live_rig) --RC pulses--> FC emulator

The operator is this module: it drives quad-control through the dashboard's HTTP API (arm, take
off, waypoints, land) exactly as a user's browser does. Nothing here feeds the emulator's truth to
the ground station; truth is only recorded, to score the flight afterwards:
  * ATE of quad-control's SLAM trajectory (its flight log, `--flight-log`) against the camera poses
    the Kinect emulator rendered, matched by the streamer's capture stamps, scored by tum-score (the
    TUM benchmark's rule: rigid alignment, 20 ms association);
  * the craft's true position against the goal (hold error), touchdown vertical speed;
  * latency per stage for each frame: emulator exposure -> streamer capture stamp -> received by
    quad-control -> SLAM pose -> first command computed from that pose (HTTP request started) ->
    request line on the firmware's serial link -> firmware reply -> first RC pulse after it (PWM).
All stamps are CLOCK_MONOTONIC (the rig maps simulated instants to it with LiveRig.sim_to_wall).
Every process is started by this module and stopped by its PID (ManagedProcess); servers listen on
127.0.0.1 only, on free ports.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import re
import shlex
import shutil
import socket
import threading
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fc_emulator import FcOptions, FlightMode, QuadParams
from kinect_emulator.poses import camera_pose_from_ned
from rgbd_protocol.stream_auth import write_key_file

from hilrig.flight import CameraMount
from hilrig.link_proxy import LinkImpairment, LinkProxy
from hilrig.machine_lock import FlightLock
from hilrig.paths import find_binary
from hilrig.procs import ManagedProcess

# What a closed-loop flight needs from the build (make build): the real programs.
REQUIRED_BINARIES = ("fw_sim", "rgbd-streamer", "quad-control", "slam-server", "tum-score")


def missing_parts() -> list[str]:
    """Names of what is not built or installed (empty: a closed-loop flight can run)."""
    from arduino.simavr_session import firmware_elf

    missing = [b for b in REQUIRED_BINARIES if find_binary(b) is None]
    if firmware_elf() is None:
        missing.append("firmware .elf (make firmware)")
    if shutil.which("fakenect") is None:
        missing.append("fakenect (libfreenect-bin)")
    return missing


def missing_load_tool() -> list[str]:
    """What the load scenario needs beyond a flight (empty: it can run)."""
    return [] if shutil.which("stress-ng") else ["stress-ng (apt: deps/apt/hil.txt)"]


def free_ports(count: int) -> list[int]:
    """`count` distinct free loopback ports. Every probe stays bound until all are read: the kernel
    may hand a port that was just released to the very next bind."""
    with contextlib.ExitStack() as stack:
        probes = [
            stack.enter_context(socket.socket(socket.AF_INET, socket.SOCK_STREAM))
            for _ in range(count)
        ]
        for s in probes:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in probes]


def free_port() -> int:
    return free_ports(1)[0]


# How the closed loop flies (quad-control "controller" keys), each measured in this rig:
#  * APM in AltHold, quad-control's height PID output read as a climb-rate stick: the APM's own
#    barometer/accelerometer loop holds the hover, so a pose gap or a lost-hold does not move the
#    craft vertically. Throttle kp 0.025 (Table 3.1) with ki = kd = 0 and AltHold's 100 us THR_DZ
#    stepped over: max height error 0.016 m in a 20 s gusty hover. Flown in Stabilize (throttle =
#    thrust, Table 3.1 PID) it was 0.03-0.13 m, and with 200-400 ms pose gaps (scenario 5) the
#    thrust loop oscillated into a fly-away; without the dead band stepped over, AltHold's 10 %
#    band left a 0.3-0.4 m height error.
#  * Roll/pitch: Table 3.1's gains in our assumed unit (percent of stick per mm; docs/control.md)
#    give a ~1 rad/s loop with 0.36 damping: the craft wandered 0.3-0.7 m in 0.15 m/s^2 gusts;
#    kp 0.05 / kd 0.035 oscillated (2 s period); kp 0.03 / kd 0.03 held ~0.15 m. Those trials
#    flew with camera->PWM p95 of 150-270 ms; since the rig's streamer stopped starving the ground
#    station (3 Dec 2026) it is 75-95 ms, and a loop with less delay takes more gain at the same
#    phase margin: kp 0.04 / kd 0.04 (the same kd/kp ratio, i.e. the same zero of the PD at 1 rad/s)
#    held 0.105 m (scenario 1), 0.115 m (scenario 2) and 0.118 m through scenario 5's stalls,
#    against 0.136 / 0.151 / 0.208 m with 0.03 in the same session (docs/hil.md).
#  * Yaw: Table 3.1's kp 0.06 %/deg turns with an 8 s time constant (a 90 deg turn took 19 s);
#    0.15 gives ~3 s and a peak rate near fr1/desk's 23 deg/s, which the front end tracks.
HIL_CONTROLLER_GAINS = {
    "roll": {"kp": 0.04, "kd": 0.04},
    "pitch": {"kp": 0.04, "kd": 0.04},
    "yaw": {"kp": 0.15},
    "throttle": {"kp": 0.025, "ki": 0.0, "kd": 0.0},
    "apm_throttle_deadband_us": 100.0,
}


def _alt_hold() -> FcOptions:
    return FcOptions(mode=FlightMode.ALT_HOLD)


def _env_flag(name: str) -> bool | None:
    """1 / 0 from the environment variable `name`; None when unset or empty."""
    value = os.environ.get(name, "").strip()
    if not value:
        return None
    if value not in ("0", "1"):
        raise ValueError(f"{name} must be 1 or 0, not {value!r}")
    return value == "1"


@dataclass(frozen=True)
class SlamFlightOptions:
    # 30 fps: the Kinect's rate; the live renderer sustains it next to the rest of the rig on 2
    # cores (measured: 30.0 fps received, 12 % of frames dropped by a busy SLAM front end).
    fps: float = 30.0
    features: str = "orb"  # ORB: the front end that fits a 30 fps budget on a CPU (docs/slam.md)
    # VO + local loop closure: measured in a 20 s gusty hover ATE 5.8 mm (VO alone 20-47 mm: its
    # drift
    # became the hold error), same front-end latency; GLC 4.9 mm but +14 ms per pose.
    backend: str = "localmap"  # slam-server back end: localmap | vo | llc | glc
    quad_params: QuadParams = field(default_factory=QuadParams)
    fc_options: FcOptions = field(default_factory=_alt_hold)
    mount: CameraMount = field(default_factory=CameraMount)
    depth_encoding: str = "rvl"  # lossless and cheap on loopback
    rgb_encoding: str = "raw"
    kinect_seed: int = 11
    key: bytes = bytes(range(0x11, 0x21))
    controller_overrides: dict = field(default_factory=lambda: dict(HIL_CONTROLLER_GAINS))
    # Faults: the WiFi link of the two stream sockets (rgbd-streamer -> quad-control) goes through
    # a LinkProxy each (hilrig.link_proxy: delay, jitter, loss stalls, sever/restore); None =
    # direct.
    stream_impairment: LinkImpairment | None = None
    # Render indices the Kinect emulator delivers all-zero (the streamer must drop them).
    blank_frames: frozenset = frozenset()
    # The rig (its threads, simavr, the Kinect renderer, rgbd-streamer: the hardware and the craft's
    # own computer) under SCHED_RR above the ground station (hilrig.realtime), so only the system
    # under test competes with the machine's other work. False: everything inherits the caller's.
    rig_realtime: bool = True
    # The load scenario: this many CPU-burning workers (stress-ng --cpu N, normal policy, nice 0)
    # run beside the ground station for the whole flight.
    cpu_burners: int = 0
    # quad-control's firmware.send_on_pose (commands on each fresh pose); None: its default.
    send_on_pose: bool | None = None
    # quad-control records the flight as MCAP in <workdir>/recording (docs/recording.md); False:
    # off.
    record: bool = True
    # More slam-server flags, for ablations (e.g. ("--mapping-rt-priority", "0")); the environment's
    # HIL_SLAM_SERVER_ARGS (split like a shell line) by default, so any scenario can be re-flown.
    slam_server_args: tuple = field(
        default_factory=lambda: tuple(shlex.split(os.environ.get("HIL_SLAM_SERVER_ARGS", "")))
    )
    # quad-control's camera.imu_rotation_prior (the APM attitude at capture rides with each frame to
    # slam-server, whose tracker predicts rotation from its change); None: quad-control's default.
    # The environment's HIL_IMU_ROTATION_PRIOR (1 / 0) sets it, so any scenario can be flown both
    # ways.
    imu_rotation_prior: bool | None = field(
        default_factory=lambda: _env_flag("HIL_IMU_ROTATION_PRIOR")
    )
    # Faults: the WiFi link between quad-control and the bridge goes through a LinkProxy
    # (`control_proxy`); None = direct.
    control_impairment: LinkImpairment | None = None
    # Builds the camera: (dump_dir, KinectOptions) -> a LiveKinect (or a subclass that injects
    # camera faults, as the soak's); None = LiveKinect.
    kinect_factory: object = None

    def validate(self) -> None:
        if not 1.0 <= self.fps <= 30.0:
            raise ValueError("fps must be in [1, 30] (a Kinect v1 delivers at most 30)")
        if self.features not in ("orb", "sift", "surf") or self.backend not in (
            "localmap",
            "vo",
            "llc",
            "glc",
        ):
            raise ValueError("features must be orb|sift|surf and backend localmap|vo|llc|glc")
        if len(self.key) != 16:
            raise ValueError("key must be 16 bytes")
        if self.cpu_burners < 0:
            raise ValueError("cpu_burners must be >= 0")


class SlamFlight:
    """One closed-loop flight. Use as a context manager; `close()` stops everything it started."""

    def __init__(self, workdir: Path, options: SlamFlightOptions | None = None) -> None:
        self.options = options or SlamFlightOptions()
        self.options.validate()
        missing = missing_parts()
        if missing:
            raise FileNotFoundError("not built / not installed: " + ", ".join(missing))
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.log_dir = self.workdir / "flight-log"
        self.recording_dir = self.workdir / "recording"
        self.dashboard_port = 0
        self.rig = None
        self.bridge = None
        self.kinect = None
        self._procs: list[tuple[str, ManagedProcess]] = []  # (program name, process)
        self.rig_scheduling = "not started"
        self._killed_on_purpose: set[str] = set()  # a scenario's fault, not a rig failure (check())
        self._saved_sched = None
        self._flight_lock: FlightLock | None = None
        self.stream_proxies: list[LinkProxy] = []
        self.control_proxy: LinkProxy | None = None
        self._qc_ports: tuple[int, int, int] | None = (
            None  # slam, rgb, depth (restart_ground_station)
        )
        self._pump_stop = threading.Event()
        self._pump: threading.Thread | None = None
        self._pump_error: BaseException | None = None
        self.operator_events: list[tuple[float, str, str]] = []  # (monotonic s, what, reply)

    # ---- start / stop -----------------------------------------------------------------------
    def start(self) -> "SlamFlight":
        from kinect_emulator.live import LiveKinect
        from kinect_emulator.renderer import KinectOptions
        from provision_key import key_record
        from rgbd_protocol.control_bridge import WifiBridgeEmulator

        from hilrig.live_rig import LiveRig

        o = self.options
        from hilrig import realtime

        try:
            # One real-time flight per machine (hilrig.machine_lock), taken before any priority is
            # raised.
            self._flight_lock = FlightLock(say=lambda m: print(m, flush=True)).acquire(
                f"SlamFlight in {self.workdir}"
            )
            # Before anything is created: the rig's threads and children inherit this thread's
            # policy.
            self._saved_sched = realtime.save_this_thread()
            self.rig_scheduling = (
                realtime.raise_this_thread() if o.rig_realtime else realtime.current_policy()
            )
            if o.cpu_burners:
                self._start(
                    "stress-ng",
                    [
                        "stress-ng",
                        "--cpu",
                        o.cpu_burners,
                        "--cpu-method",
                        "matrixprod",
                        "--metrics-brief",
                    ],
                    system=True,
                )
            self.rig = LiveRig(
                key_record(o.key),
                fc_options=o.fc_options,
                quad_params=o.quad_params,
                workdir=self.workdir,
            ).start()
            self.bridge = WifiBridgeEmulator(self.rig.transact).start()
            if o.control_impairment is not None:
                self.control_proxy = LinkProxy(self.bridge.port, o.control_impairment)
            slam_port, rgb_port, depth_port = free_ports(3)
            self._qc_ports = (slam_port, rgb_port, depth_port)
            self._start(
                "slam-server",
                [
                    find_binary("slam-server"),
                    "--bind",
                    "127.0.0.1",
                    "--port",
                    slam_port,
                    "--features",
                    o.features,
                    "--backend",
                    o.backend,
                    # Each map's per-frame tracking stages (frames.csv: wall and CPU ms, lock
                    # waits, relocalised), written when the map ends: where SLAM spent a flight.
                    "--tables-dir",
                    str(self.workdir / "slam-tables"),
                    # The deployed setting (run-offboard): each map is checkpointed, so
                    # a slam-server restarted after a crash resumes the flight's map and world
                    # frame.
                    *(
                        ("--checkpoint-dir", str(self.workdir / "slam-checkpoints"))
                        if o.backend == "localmap"
                        else ()
                    ),
                    *o.slam_server_args,
                ],
                system=True,
            )
            self._start_quad_control((slam_port, rgb_port, depth_port))
            self.kinect = (o.kinect_factory or LiveKinect)(
                self.workdir / "kinect-dump",
                KinectOptions(
                    fps=o.fps, seed=o.kinect_seed, blank_frames=frozenset(o.blank_frames)
                ),
            )
            if o.stream_impairment is not None:
                self.stream_proxies = [
                    LinkProxy(p, o.stream_impairment) for p in (rgb_port, depth_port)
                ]
                rgb_port, depth_port = (p.port for p in self.stream_proxies)
            self.kinect.start()
            self._pump = threading.Thread(target=self._pump_frames, name="kinect-pump", daemon=True)
            self._pump.start()
            self._start(
                "rgbd-streamer",
                self.kinect.direct_streamer_command(
                    find_binary("rgbd-streamer"),
                    "--config",
                    self._write_streamer_config(),
                    "--host",
                    "127.0.0.1",
                    "--rgb-port",
                    str(rgb_port),
                    "--depth-port",
                    str(depth_port),
                    "--depth-encoding",
                    o.depth_encoding,
                    "--rgb-encoding",
                    o.rgb_encoding,
                    "--stats-period",
                    "0",
                ),
                env=self.kinect.streamer_env(),
            )
        except BaseException:
            self.close()
            raise
        return self

    def close(self) -> None:
        self._pump_stop.set()
        if self._pump is not None:
            self._pump.join(timeout=5)
        # The camera first: the streamer's libfreenect thread returns only at the next INDEX line
        # or end of file (kinect_emulator.live), so it must see EOF before it is asked to stop.
        if self.kinect is not None:
            self.kinect.close()
        for _, p in reversed(self._procs):
            p.stop()
        for proxy in self.stream_proxies:
            proxy.close()
        if self.control_proxy is not None:
            self.control_proxy.close()
        if self.bridge is not None:
            self.bridge.close()
        if self._saved_sched is not None:
            from hilrig import realtime

            realtime.restore_this_thread(self._saved_sched)
            self._saved_sched = None
        if self.rig is not None:
            rig, self.rig = self.rig, None
            rig.close()
        if self._flight_lock is not None:
            self._flight_lock.release()
            self._flight_lock = None

    def __enter__(self) -> "SlamFlight":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    def kill_ground_station(self) -> None:
        """Scenario 3: quad-control dies (SIGKILL, no goodbye); slam-server and the craft go on."""
        for name, p in self._procs:
            if name == "quad-control" and p.alive():
                p.proc.kill()
                p.proc.wait(timeout=5)

    def restart_ground_station(self, log_dir: Path, recording_dir: Path) -> None:
        """A new quad-control (the operator starts the ground station for the next flight): the
        old one, alive or killed, is stopped by its PID; the new one gets the same configuration
        with its own flight log and recording folder, and the dashboard port it prints."""
        if self._qc_ports is None:
            raise RuntimeError("the flight is not started")
        for name, p in self._procs:
            if name == "quad-control":
                p.stop()
        self._procs = [(n, p) for n, p in self._procs if n != "quad-control"]
        self.log_dir, self.recording_dir = Path(log_dir), Path(recording_dir)
        self.log_dir.parent.mkdir(parents=True, exist_ok=True)
        self._start_quad_control(self._qc_ports, self.log_dir.parent / "quad-control.log")

    def _start_quad_control(
        self, ports: tuple[int, int, int], log_path: Path | None = None
    ) -> None:
        """quad-control on the flight's SLAM and stream ports, with this flight's log folder; sets
        the dashboard port it prints."""
        config = self._write_quad_control_config(*ports)
        qc = self._start(
            "quad-control",
            [
                find_binary("quad-control"),
                "--config",
                config,
                "--port",
                "0",
                "--flight-log",
                self.log_dir,
            ],
            system=True,
            log_path=log_path,
        )
        self.dashboard_port = self._wait_dashboard_port(qc)

    def process_ids(self) -> dict[str, int]:
        """PID of each running process the flight started, by program name."""
        out = {name: p.pid for name, p in self._procs if p.alive()}
        if self.kinect is not None and getattr(self.kinect, "_proc", None) is not None:
            if self.kinect.alive():
                out["kinect-renderer"] = self.kinect._proc.pid
        if self.rig is not None:
            fw = getattr(self.rig._session, "_proc", None)
            if fw is not None and fw.poll() is None:
                out["fw_sim"] = fw.pid
        return out

    def kill_slam_server(self) -> None:
        """slam-server dies mid-flight (SIGKILL: no goodbye, its maps are gone)."""
        # Marked before the kill: check() on another thread must never see it dead and unmarked.
        self._killed_on_purpose.add("slam-server")
        for name, p in self._procs:
            if name == "slam-server" and p.alive():
                p.proc.kill()
                p.proc.wait(timeout=5)

    def restart_slam_server(self) -> None:
        """A new slam-server on the same port (what a supervisor would do), with the same arguments:
        quad-control's link reconnects with its map id; the new server resumes that map from
        its map checkpoint (--checkpoint-dir) when there is one, else a new map starts and
        quad-control re-anchors it."""
        old = [p for name, p in self._procs if name == "slam-server"]
        if not old or old[-1].alive():
            raise RuntimeError("slam-server is still running: kill_slam_server() first")
        argv = list(old[-1].argv)
        restarts = len(
            list(self.workdir.glob("slam-server*.log"))
        )  # names this server's log and tables
        if "--tables-dir" in argv:  # the new server numbers its maps from 1 again
            i = argv.index("--tables-dir") + 1
            argv[i] = str(self.workdir / f"slam-tables-{restarts}")
        self._procs = [(n, p) for n, p in self._procs if p is not old[-1]]
        old[-1].stop()
        log = self.workdir / "slam-server.log"
        log.rename(self.workdir / f"slam-server-{restarts}.log")
        p = ManagedProcess(argv, log)
        self._procs.append(("slam-server", p))
        self._killed_on_purpose.discard("slam-server")

    def sever_stream(self) -> None:
        """Scenario 4: the stream link drops (both sockets; the streamer reconnects with
        backoff)."""
        if not self.stream_proxies:
            raise RuntimeError("no stream proxies: set SlamFlightOptions.stream_impairment")
        for proxy in self.stream_proxies:
            proxy.sever()

    def restore_stream(self) -> None:
        for proxy in self.stream_proxies:
            proxy.restore()

    def _start(
        self, name: str, argv, env=None, system: bool = False, log_path: Path | None = None
    ) -> ManagedProcess:
        """`system`: a process of the ground station (or the load), started under the normal policy
        whatever the rig runs under (it raises its own real-time threads, as on its own machine)."""
        from hilrig.realtime import normal_policy_argv

        argv = [str(a) for a in argv]
        p = ManagedProcess(
            normal_policy_argv(argv) if system else argv,
            log_path or self.workdir / f"{name}.log",
            env=env,
        )
        self._procs.append((name, p))
        return p

    def scheduling(self) -> dict:
        """What each part runs under: the rig's policy, and the lines in which quad-control and
        slam-server logged their threads' scheduling (or why real-time was refused)."""
        out = {"rig": self.rig_scheduling}
        for name, p in self._procs:
            if name in ("quad-control", "slam-server"):
                out[name] = re.findall(
                    r"^(?:quad-control|slam-server): (.+ thread: .*)$", p.log_text(), re.M
                )[:6]
        return out

    def _stream_key_file(self) -> Path:
        """The craft's stream key (mode 0600), read by both the streamer and quad-control."""
        path = self.workdir / "stream.key"
        if not path.exists():
            write_key_file(path)
        return path

    def _write_streamer_config(self) -> Path:
        path = self.workdir / "rgbd-streamer.yaml"
        path.write_text(
            self.kinect.streamer_config_yaml(f"stream_key_file: {self._stream_key_file()}\n")
        )
        return path

    def _write_quad_control_config(self, slam_port: int, rgb_port: int, depth_port: int) -> Path:
        o = self.options
        cfg = {
            "dashboard": {"bind_address": "127.0.0.1", "port": 8080},
            "stream": {
                "source": "receiver",
                "bind_address": "127.0.0.1",
                "rgb_port": rgb_port,
                "depth_port": depth_port,
                "key_file": str(self._stream_key_file()),
            },
            "slam": {"mode": "server", "host": "127.0.0.1", "port": slam_port},
            "firmware": {
                "enabled": True,
                "host": "127.0.0.1",
                "port": self.control_proxy.port if self.control_proxy else self.bridge.port,
                "key_hex": o.key.hex(),
                **({} if o.send_on_pose is None else {"send_on_pose": o.send_on_pose}),
            },
            "camera": {
                "mount_pitch_down_deg": o.mount.mount_pitch_down_deg,
                **(
                    {}
                    if o.imu_rotation_prior is None
                    else {"imu_rotation_prior": o.imu_rotation_prior}
                ),
            },
            "recording": {"enabled": o.record, "dir": str(self.recording_dir)},
        }
        if o.controller_overrides:
            cfg["controller"] = dict(o.controller_overrides)
        path = self.workdir / "quad-control.json"
        path.write_text(json.dumps(cfg, indent=2))
        return path

    def _wait_dashboard_port(self, qc: ManagedProcess, timeout_s: float = 20.0) -> int:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            m = re.search(r"dashboard on http://127\.0\.0\.1:(\d+)/", qc.log_text())
            if m:
                return int(m.group(1))
            if not qc.alive():
                raise RuntimeError("quad-control exited:\n" + qc.log_text()[-2000:])
            time.sleep(0.05)
        raise RuntimeError(
            "quad-control did not print its dashboard port:\n" + qc.log_text()[-2000:]
        )

    # ---- camera -------------------------------------------------------------------------------
    def _pump_frames(self) -> None:
        """Requests one frame per camera period at the craft's current true pose (the rig's newest
        step). The Kinect emulator drops a request while it is still rendering (a camera never
        queues), so a slow machine shows up as a lower delivered frame rate, not as latency."""
        period = 1.0 / self.options.fps
        mount = self.options.mount
        next_t = time.monotonic()
        try:
            while not self._pump_stop.is_set():
                next_t += period
                delay = next_t - time.monotonic()
                if delay > 0:
                    self._pump_stop.wait(delay)
                else:
                    next_t = time.monotonic()  # behind: restart the grid, do not burst
                self.kinect.submit(time.monotonic(), camera_room_pose(self.rig.snapshot(), mount))
        except BaseException as e:  # reported by check()
            self._pump_error = e

    # ---- operator (the dashboard's HTTP API) -----------------------------------------------------
    def _http(self, method: str, path: str, body: dict | None = None, timeout_s: float = 5.0):
        url = f"http://127.0.0.1:{self.dashboard_port}{path}"
        data = json.dumps(body).encode() if body is not None else None
        req = urllib.request.Request(url, data=data, method=method)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(req, timeout=timeout_s) as r:
                return r.status, json.loads(r.read() or b"null")
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read() or b"null")

    def state(self) -> dict:
        status, body = self._http("GET", "/api/state")
        if status != 200:
            raise RuntimeError(f"/api/state answered {status}: {body}")
        return body

    def command(self, name: str) -> dict:
        status, body = self._http("POST", "/api/command", {"command": name})
        self.operator_events.append((time.monotonic(), name, json.dumps(body)))
        if status != 200:
            raise RuntimeError(f"command {name} refused ({status}): {body}")
        return body

    def waypoint(self, x_m: float, y_m: float) -> dict:
        status, body = self._http("POST", "/api/waypoint", {"x_m": x_m, "y_m": y_m})
        self.operator_events.append(
            (time.monotonic(), f"waypoint {x_m:.2f},{y_m:.2f}", json.dumps(body))
        )
        if status != 200:
            raise RuntimeError(f"waypoint refused ({status}): {body}")
        return body

    def manual(
        self,
        forward_m: float = 0.0,
        left_m: float = 0.0,
        up_m: float = 0.0,
        yaw_ccw_deg: float = 0.0,
    ) -> dict:
        """The dashboard's manual step (POST /api/manual): moves the hold setpoint, turns the
        heading."""
        body = {"forward_m": forward_m, "left_m": left_m, "up_m": up_m, "yaw_ccw_deg": yaw_ccw_deg}
        status, reply = self._http("POST", "/api/manual", body)
        self.operator_events.append(
            (time.monotonic(), f"manual {json.dumps(body)}", json.dumps(reply))
        )
        if status != 200:
            raise RuntimeError(f"manual step refused ({status}): {reply}")
        return reply

    def wait_until(self, predicate, timeout_s: float, what: str, poll_s: float = 0.1) -> dict:
        """Polls /api/state until predicate(state) holds; raises with the last state otherwise."""
        end = time.monotonic() + timeout_s
        st: dict = {}
        while time.monotonic() < end:
            self.check()
            st = self.state()
            if predicate(st):
                return st
            time.sleep(poll_s)
        raise TimeoutError(
            f"{what}: not within {timeout_s:.0f} s; last state={st.get('state')} "
            f"tracking={st.get('tracking')} event={st.get('last_event')} slam={st.get('slam')} "
            f"stream={st.get('stream')} floor={st.get('floor')}"
        )

    def hold_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.check()
            time.sleep(min(0.2, max(0.0, end - time.monotonic())))

    def check(self) -> None:
        """Raises if a part of the rig died (a process exited, the pump or rig thread failed)."""
        if self._pump_error is not None:
            raise RuntimeError(f"camera pump failed: {self._pump_error!r}")
        for name, p in self._procs:
            if not p.alive() and name != "quad-control" and name not in self._killed_on_purpose:
                raise RuntimeError(f"{name} exited:\n" + p.log_text()[-2000:])

    # ---- scoring ------------------------------------------------------------------------------
    def poses(self) -> list[dict]:
        return _read_csv(self.log_dir / "poses.csv")

    def commands(self) -> list[dict]:
        return _read_csv(self.log_dir / "commands.csv")

    def frames(self) -> list[dict]:
        return _read_csv(self.log_dir / "frames.csv")

    def ate(self) -> dict:
        """quad-control's SLAM trajectory against the rendered camera poses (tum-score)."""
        from kinect_emulator.live import match_capture_stamps
        from kinect_emulator.poses import rotation_to_quaternion_xyzw

        tracked = [p for p in self.poses() if p["tracking"] == "1"]
        stamps = [int(p["capture_us"]) for p in tracked]
        matched = match_capture_stamps(self.kinect.records(), stamps)
        gt = self.workdir / "groundtruth.tum"
        n = 0
        with open(gt, "w") as f:
            f.write(
                "# emulator truth: T_room_cam of the rendered frame "
                "at the streamer's capture stamp\n"
            )
            for stamp, rec in zip(stamps, matched, strict=False):
                if rec is None:
                    continue
                T = np.asarray(rec.T_room_cam)
                q = rotation_to_quaternion_xyzw(T[:3, :3])
                f.write(
                    f"{stamp / 1e6:.6f} {T[0, 3]:.6f} {T[1, 3]:.6f} {T[2, 3]:.6f} "
                    + " ".join(f"{v:.9f}" for v in q)
                    + "\n"
                )
                n += 1
        if n < 3:
            return {
                "error": f"only {n} tracked frames matched to rendered poses",
                "tracked": len(tracked),
            }
        p = ManagedProcess(
            [find_binary("tum-score"), gt, self.log_dir / "trajectory.tum"],
            self.workdir / "tum-score.json",
            stderr_path=self.workdir / "tum-score.err",
        )
        rc = p.wait(120)
        p.stop()
        if rc != 0:
            return {"error": (self.workdir / "tum-score.err").read_text()[-500:]}
        m = json.loads((self.workdir / "tum-score.json").read_text())
        return {
            k: m[k]
            for k in ("ate_rmse_m", "ate_max_m", "rpe_trans_rmse_mm", "rpe_rot_rmse_deg", "pairs")
            if k in m
        }

    def latency(self) -> dict:
        """Median / p95 per stage over the frames whose pose reached the motors (ms)."""
        from kinect_emulator.live import match_capture_stamps

        poses = {int(p["capture_us"]): p for p in self.poses() if p["tracking"] == "1"}
        # First command computed from each pose.
        first_cmd: dict[int, dict] = {}
        for c in self.commands():
            cap = int(c["pose_capture_us"])
            if cap in poses and cap not in first_cmd:
                first_cmd[cap] = c
        # Serial/firmware/PWM timings of each command, by sequence number.
        by_seq = {}
        for t in self.rig.timings():
            seq = _seq_of(t.line)
            if seq is not None and t.first_pulse_after_us is not None:
                by_seq[seq] = t
        caps = [cap for cap in sorted(first_cmd) if int(first_cmd[cap]["seq"]) in by_seq]
        recs = match_capture_stamps(self.kinect.records(), caps)
        timings = [by_seq[int(first_cmd[cap]["seq"])] for cap in caps]
        # One interpolation over the whole flight (the rig's step table is copied once).
        walls = (
            self.rig.sim_to_wall(
                [[t.injected_us, t.reply_end_us, t.first_pulse_after_us] for t in timings]
            )
            if timings
            else []
        )
        rows = []
        for cap, rec, (inj, rep, pwm) in zip(caps, recs, walls, strict=False):
            c, p = first_cmd[cap], poses[cap]
            row = {
                "capture_to_received": (int(p["received_us"]) - cap) / 1e3,
                "received_to_pose": (int(p["pose_us"]) - int(p["received_us"])) / 1e3,
                "pose_to_command": (int(c["send_us"]) - int(p["pose_us"])) / 1e3,
                "command_to_serial": inj * 1e3 - int(c["send_us"]) / 1e3,
                "serial_to_reply": (rep - inj) * 1e3,
                "reply_to_pwm": (pwm - rep) * 1e3,
                "capture_to_pwm": pwm * 1e3 - cap / 1e3,
            }
            if rec is not None:
                row["exposure_to_capture"] = cap / 1e3 - rec.t_mono_s * 1e3
                row["exposure_to_pwm"] = (pwm - rec.t_mono_s) * 1e3
            rows.append(row)
        out: dict = {"frames": len(rows)}
        for key in rows[0] if rows else []:
            v = np.array([r[key] for r in rows if key in r])
            out[key] = {
                "median_ms": round(float(np.median(v)), 1),
                "p95_ms": round(float(np.percentile(v, 95)), 1),
            }
        return out

    def scores(self) -> dict:
        """The figures every flight reports: ATE, latency per stage, stream/SLAM counts."""
        return {
            "ate": self.ate(),
            "latency_ms": self.latency(),
            "stream": self.stream_stats(),
            "scheduling": self.scheduling(),
            "load_average": _load_average(),
            "thread_cpu_s": self.thread_cpu(),
            "slam_tracking": self.slam_tracking(),
        }

    def slam_tracking(self) -> dict:
        """slam-server's per-frame table (--tables-dir, every map of every slam-server run):
        frames tracked and lost, and how each tracked pose was found."""
        rows = [
            r
            for path in sorted(self.workdir.glob("slam-tables*/map-*/frames.csv"))
            for r in _read_csv(path)
        ]
        if not rows:
            return {"frames": 0}

        def count(column: str) -> int:
            return sum(1 for r in rows if r.get(column) == "1")

        cpu = np.array([float(r["frontend_cpu_ms"]) for r in rows if r.get("frontend_cpu_ms")])
        return {
            "frames": len(rows),
            "lost": sum(1 for r in rows if r.get("state") == "lost"),
            "relocalised": count("relocalised"),
            "cross_checked": count("cross_checked"),
            "attitude_predicted": count("attitude_predicted"),
            "keyframes": count("keyframe"),
            "tracking_cpu_ms": {
                "median": round(float(np.median(cpu)), 1),
                "p95": round(float(np.percentile(cpu, 95)), 1),
            }
            if cpu.size
            else None,
        }

    def thread_cpu(self) -> dict:
        """CPU seconds per named thread of each ground-station and onboard process so far
        (hilrig.thread_cpu), to say where the machine's CPU went in this flight."""
        from hilrig.thread_cpu import thread_cpu_s

        return {
            name: thread_cpu_s(p.pid)
            for name, p in self._procs
            if name in ("quad-control", "slam-server", "rgbd-streamer") and p.alive()
        }

    def stream_stats(self) -> dict:
        frames = self.frames()
        poses = self.poses()
        span = (
            (int(frames[-1]["received_us"]) - int(frames[0]["received_us"])) / 1e6
            if len(frames) > 1
            else 0
        )
        return {
            "frames_received": len(frames),
            "received_fps": round((len(frames) - 1) / span, 2) if span > 0 else 0.0,
            "slam_results": len(poses),
            "slam_tracked": sum(p["tracking"] == "1" for p in poses),
            "kinect": self.kinect.stats(),
        }


def _load_average() -> str | None:
    """/proc/loadavg's 1/5/15-minute averages (every timing is reported with the machine's load)."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return None


def _read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def _seq_of(line: str) -> int | None:
    m = re.search(r"[?&]seq=(\d+)", line)
    return int(m.group(1)) if m else None


def camera_room_pose(snap, mount: CameraMount) -> np.ndarray:
    """T_room_cam of the craft in FC-emulator snapshot `snap` (room: x north, y west, z up from
    the floor)."""
    return camera_pose_from_ned(
        snap.pos_ned_m,
        snap.roll_rad,
        snap.pitch_rad,
        snap.yaw_rad,
        mount_pitch_down_deg=mount.mount_pitch_down_deg,
        origin_room_m=mount.origin_room_m,
    )


def camera_room_position(snap, mount: CameraMount) -> np.ndarray:
    """The camera's true position in the room frame."""
    return camera_room_pose(snap, mount)[:3, 3]


def goal_in_room(start_cam_room: np.ndarray, floor_goal: tuple[float, float, float]) -> np.ndarray:
    """quad-control's floor frame (origin on the floor under the camera at start-up, x along the
    camera's heading then, y left, z up) in the room frame, for a craft that starts facing north
    (room +x; room +y is west, i.e. left): a translation by the start position on the floor."""
    x, y, z = floor_goal
    return np.array([start_cam_room[0] + x, start_cam_room[1] + y, z])


def hold_error(
    history, goal_room: np.ndarray, mount: CameraMount, from_us: float, to_us: float
) -> dict:
    """Error of the camera's true position against a goal in the room frame over
    [from_us, to_us]."""
    sel = [s for s in history if from_us <= s.t_us <= to_us]
    if not sel:
        return {"samples": 0}
    pos = np.array([camera_room_position(s, mount) for s in sel])
    horiz = np.hypot(pos[:, 0] - goal_room[0], pos[:, 1] - goal_room[1])
    vert = np.abs(pos[:, 2] - goal_room[2])
    err = np.hypot(horiz, vert)
    return {
        "max_m": round(float(err.max()), 3),
        "rms_m": round(float(np.sqrt(np.mean(err**2))), 3),
        "max_horizontal_m": round(float(horiz.max()), 3),
        "max_vertical_m": round(float(vert.max()), 3),
        "samples": len(sel),
    }
