r"""Recording on vs off, side by side: what MCAP recording costs quad-control (a benchmark; prints
numbers, asserts nothing).

    PYTHONPATH=hil:protocol/python:offboard/quadcontrol \
        .venv/bin/python hil/recording_bench.py [--seconds 30] [--pairs 2]

Runs quad-control on the TUM replay (tests/data/fr1_xyz_first30 bouncing, 30 fps) with in-process
SLAM and the firmware double behind the HIL WiFi-bridge emulator (loopback), armed, alternately with
--record and --no-record (`--pairs` times each, so the machine's load drifts over both), each run
with --flight-log. Per run:
  * frame received -> first command carrying its pose (ms, median / p95), from the flight log
    (frames.csv, commands.csv: the ground station's share of camera -> PWM, on one clock);
  * quad-control's CPU time per received frame (utime + stime from /proc/PID/stat over the window);
  * with recording: the writer thread's CPU per frame, bytes per minute, drops;
  * the load average during the run.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import statistics
import sys
import time
import urllib.request

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path[:0] = [
    str(REPO / "protocol/python"),
    str(REPO / "hil"),
    str(REPO / "offboard/quadcontrol"),
]

from hilrig.thread_cpu import process_cpu_s as cpu_s  # noqa: E402
from quadcontrol_harness.firmware_double import FirmwareDouble  # noqa: E402
from quadcontrol_harness.quad_control import KEY, QuadControl, write_config  # noqa: E402
from rgbd_protocol.control_bridge import WifiBridgeEmulator  # noqa: E402


def received_to_command_ms(log_dir: pathlib.Path, t_from_us: int) -> list[float]:
    received = {}
    with open(log_dir / "frames.csv") as f:
        for row in csv.DictReader(f):
            received[int(row["capture_us"])] = int(row["received_us"])
    first_send: dict[int, int] = {}
    with open(log_dir / "commands.csv") as f:
        for row in csv.DictReader(f):
            cap = int(row["pose_capture_us"])
            if cap >= 0 and cap not in first_send:
                first_send[cap] = int(row["send_us"])
    # A bouncing replay re-delivers capture stamps: keep the latest reception before the send.
    return [
        (send - received[cap]) / 1000.0
        for cap, send in first_send.items()
        if cap in received and t_from_us <= received[cap] <= send
    ]


def one_run(binary: str, bridge_port: int, record: bool, seconds: float) -> dict:
    tmp = pathlib.Path("/tmp") / f"qc-recmeasure-{time.time_ns()}"
    tmp.mkdir()
    args = [
        "--config",
        str(write_config(tmp, bridge_port)),
        "--port",
        "0",
        "--flight-log",
        str(tmp / "log"),
    ]
    args += ["--record", str(tmp / "rec")] if record else ["--no-record"]
    qc = QuadControl(pathlib.Path(binary), args)
    try:

        def state() -> dict:
            with urllib.request.urlopen(qc.url + "api/state", timeout=5) as r:
                return json.load(r)

        req = urllib.request.Request(
            qc.url + "api/command",
            data=b'{"command": "arm"}',
            method="POST",
            headers={"Content-Type": "application/json"},
        )
        urllib.request.urlopen(req, timeout=5).read()
        time.sleep(3)  # start-up: SLAM set-up, first poses
        a, c0, load0 = state(), cpu_s(qc.proc.pid), os.getloadavg()[0]
        t0_us = time.monotonic_ns() // 1000
        time.sleep(seconds)
        b, c1, load1 = state(), cpu_s(qc.proc.pid), os.getloadavg()[0]
    finally:
        qc.stop()
    frames = b["stream"]["frames"] - a["stream"]["frames"]
    lat = received_to_command_ms(tmp / "log", t0_us)
    q = statistics.quantiles(lat, n=20) if len(lat) >= 20 else [float("nan")] * 19
    out = {
        "record": record,
        "frames": frames,
        "fps": round(frames / seconds, 1),
        "received_to_command_ms_median": round(statistics.median(lat), 2) if lat else None,
        "received_to_command_ms_p95": round(q[18], 2),
        "poses": len(lat),
        "cpu_ms_per_frame": round(1000 * (c1 - c0) / max(1, frames), 2),
        "load_average": [round(load0, 2), round(load1, 2)],
    }
    if record:
        ra, rb = a["recording"], b["recording"]
        files = sorted((tmp / "rec").glob("*.mcap"))
        size = sum(f.stat().st_size for f in files)
        out.update(
            {
                "writer_cpu_ms_per_frame": round(
                    (rb["writer_cpu_ms"] - ra["writer_cpu_ms"]) / max(1, frames), 2
                ),
                "mb_per_min": round((rb["bytes"] - ra["bytes"]) / 1048576 / (seconds / 60), 2),
                "file_mb": round(size / 1048576, 2),
                "dropped_queue_full": rb["dropped_queue_full"],
            }
        )
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--bin", default=str(REPO / "build/bin/quad-control"))
    args = ap.parse_args()
    double = FirmwareDouble(KEY)
    bridge = WifiBridgeEmulator(double.transact).start()
    runs = []
    try:
        for _ in range(args.pairs):
            for record in (True, False):
                r = one_run(args.bin, bridge.port, record, args.seconds)
                print(json.dumps(r), flush=True)
                runs.append(r)
    finally:
        bridge.close()
    print(
        "record | fps | received->command median / p95 ms | quad-control CPU ms/frame | "
        "writer CPU ms/frame | MB/min | load"
    )
    for r in runs:
        print(
            f"{'on ' if r['record'] else 'off'} | {r['fps']} | "
            f"{r['received_to_command_ms_median']} / "
            f"{r['received_to_command_ms_p95']} | {r['cpu_ms_per_frame']} | "
            f"{r.get('writer_cpu_ms_per_frame', '-')} | "
            f"{r.get('mb_per_min', '-')} | {r['load_average']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
