"""HIL scenario 2 with quad-control's MCAP recording on or off: what the recording holds and costs.

    PYTHONPATH=hil:protocol/python:firmware/tools:offboard/recorder \
        .venv/bin/python hil/recording_flight.py --record on  --out out/rec-hil-on
    ... --record off --out out/rec-hil-off

Flies hilrig.missions.scenario2 (take off, hold, two waypoints, land) exactly as `make demo`, with
SlamFlightOptions.record set, and writes DIR/recording-report.json with:
  * the flight's camera (capture stamp) -> PWM latency median / p95 and the load average (the figure
    to compare between --record on and off, run back to back on the same machine);
  * with recording on: the file's size, MB per minute, channels and message counts (read back by the
    Python `mcap` reader with CRCs checked), the writer thread's CPU per received frame (from
    /api/state just before landing ends), drops; and the replay of the recorded frames through
    slam-eval compared with the poses quad-control flew on (flight_recording.replay).
Figures only: nothing here passes or fails (docs/recording.md quotes the runs).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

from hilrig import missions
from hilrig.paths import REPO_ROOT
from hilrig.slam_flight import SlamFlight, SlamFlightOptions, missing_parts


def recording_figures(flight: SlamFlight, state: dict, out: Path, replay_it: bool = True) -> dict:
    from flight_recording.reader import read
    from flight_recording.replay import run as replay

    files = sorted(flight.recording_dir.glob("*.mcap"))
    size = sum(f.stat().st_size for f in files)
    rec = read(files[-1])  # SIGKILLed after the stop grace: no summary, read in streaming order
    span_min = rec.span_s() / 60.0
    r = state["recording"]
    frames = state["stream"]["frames"]
    figures = {
        "files": [f.name for f in files],
        "bytes": size,
        "span_s": round(rec.span_s(), 2),
        "mb_per_min": round(size / 1048576 / span_min, 2) if span_min > 0 else None,
        "complete": rec.complete,
        "read_errors": rec.errors[:3],
        "counts": rec.counts(),
        "writer_cpu_ms": round(r["writer_cpu_ms"], 1),
        "frames_received": frames,
        "writer_cpu_ms_per_frame": round(r["writer_cpu_ms"] / max(1, frames), 3),
        "encode_ms_per_recorded_frame": round(r["encode_ms_per_frame"], 3),
        "dropped_queue_full": r["dropped_queue_full"],
        "images_dropped": r.get("images_dropped"),
        "frames_recorded": r.get("frames_recorded"),
        "frames_encoded_here": r.get("frames_encoded_here"),
        "queued_mb_peak": round(r.get("queued_bytes_peak", 0) / 1048576, 2),
    }
    if not replay_it:
        return figures
    try:
        figures["replay"] = replay(
            files[-1],
            out / "replay",
            REPO_ROOT / "build" / "bin" / "slam-eval",
            REPO_ROOT / "build" / "bin" / "tum-score",
        )
    except Exception as e:  # noqa: BLE001 - the flight's figures still count
        figures["replay"] = {"error": f"{type(e).__name__}: {e}"}
    return figures


def with_image_rate(every_n: int) -> None:
    """Sets recording.image_every_n_frames in the quad-control config SlamFlight writes."""
    write = SlamFlight._write_quad_control_config

    def patched(self, *a, **k) -> Path:
        path = write(self, *a, **k)
        cfg = json.loads(path.read_text())
        cfg.setdefault("recording", {})["image_every_n_frames"] = every_n
        path.write_text(json.dumps(cfg, indent=2))
        return path

    SlamFlight._write_quad_control_config = patched


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--record", choices=("on", "off"), required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--hold-s", type=float, default=10.0)
    ap.add_argument(
        "--image-every",
        type=int,
        default=None,
        help="recording.image_every_n_frames for this flight (default: quad-control's, 1)",
    )
    ap.add_argument(
        "--rgb-encoding",
        choices=("raw", "jpeg"),
        default="raw",
        help="the streamer's RGB encoding (the rig's default raw: the recorder then JPEG-encodes "
        "every frame; jpeg: the shipped streamer's, stored as it came)",
    )
    ap.add_argument("--no-replay", action="store_true", help="skip the replay through SLAM")
    args = ap.parse_args(argv)
    missing = missing_parts()
    if missing:
        print("recording_flight: cannot fly: " + ", ".join(missing), file=sys.stderr)
        return 2
    if args.out.exists():
        shutil.rmtree(args.out)
    t0 = time.monotonic()
    load_before = os.getloadavg()
    if args.image_every is not None:
        with_image_rate(args.image_every)
    options = SlamFlightOptions(record=args.record == "on", rgb_encoding=args.rgb_encoding)
    with SlamFlight(args.out, options) as flight:
        try:
            report = missions.scenario2(flight, hold_s=args.hold_s)
        except (TimeoutError, RuntimeError) as e:
            report = {"aborted": str(e)}
        report.update(flight.scores())
        state = flight.state()
    out = {
        "record": args.record,
        "rgb_encoding": args.rgb_encoding,
        "image_every_n_frames": args.image_every,
        "wall_s": round(time.monotonic() - t0, 1),
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "aborted": report.get("aborted"),
        "latency_ms": report.get("latency_ms"),
        "ate": report.get("ate"),
        "stream": report.get("stream"),
    }
    if args.record == "on":
        out["recording"] = recording_figures(flight, state, args.out, replay_it=not args.no_replay)
    (args.out / "recording-report.json").write_text(json.dumps(out, indent=2, default=str))
    print(json.dumps(out, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
