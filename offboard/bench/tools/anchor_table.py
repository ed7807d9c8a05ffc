#!/usr/bin/env python3
"""Prints the fast-motion and anchor table of `make bench` with its verdicts.

Reads OUT/anchor/<sequence>_<mode>_<variant>/metrics.json, written by offboard/bench/bench.sh:
the default system, slam-eval --mode wait and --mode realtime, with the new-segment restart on (the
default, variant restart_on) and off (restart_off), with gravity from the Kinect's accelerometer
(accel-gravity_on; TUM carries no flight-controller attitude, the default source, so the default
measures no gravity there), and with the colour camera fitted as a global shutter
(rolling-shutter_off; real sequences only: the default models the rolling shutter, and rendered
frames have none), on the real sequences in DATA
and on the manoeuvres rendered by hil/tools/render_tum.py (hil_*); and
OUT/anchor/orbslam2_<name>.json, ORB-SLAM2's published runs scored by `slam-eval score` on the
same frames. One row per sequence and mode: ATE, frames lost, segments started, local BAs
interrupted per 100 frames, and real time against wait mode. Real time depends on the machine's
timing, so the default is also run again in real time (OUT/anchor_repeats/<sequence>_<k>/,
REALTIME_REPEATS in all) and the real-time verdicts take the median of the runs; so is the
global-shutter variant (OUT/anchor_rs_repeats/), reported beside them.

Targets (the SLAM fast-motion capability): 0 lost frames on every sequence in both modes;
fr1_xyz_first300 in real time <= 0.0105 m (below ORB-SLAM2's median on the same frames) with 0
frames dropped; real-time ATE <= 1.05 x wait-mode ATE on every sequence. Standard library only.
"""

import json
import sys
from pathlib import Path
from statistics import median

XYZ_TARGET_M = 0.0105
# The variant the verdicts judge: the default system (TrackerOptions::restart_when_lost on).
DEFAULT_VARIANT = "restart on"
VARIANTS = ("_restart_", "_accel-gravity_", "_rolling-shutter_")


def variant_of(run_name: str) -> str:
    """'restart on', 'restart off', 'accel-gravity on' or 'rolling-shutter off' from a run
    folder's name."""
    for v in VARIANTS:
        if v in run_name:
            return v.strip("_") + " " + run_name.rsplit("_", 1)[-1]
    return "?"


RT_OVER_WAIT_MAX = 1.05


def realtime_repeats(out_dir: Path, seq: str, folder: str = "anchor_repeats") -> list[dict]:
    """metrics.json of a variant's repeated real-time runs on `seq` (the default's: folder
    anchor_repeats; the global-shutter variant's: anchor_rs_repeats)."""
    runs = sorted(p for p in (out_dir / folder).glob(f"{seq}_*") if p.is_dir())
    return [m for m in (load(p / "metrics.json") for p in runs) if m and "ate_rmse_m" in m]


def realtime_runs(out_dir: Path, table: dict, seq: str, variant: str, folder: str) -> tuple:
    """A variant's real-time runs on `seq`: the anchor run's row in `table` (None without one),
    the ATEs of it and its repeats in OUT/<folder>/, and the repeats' metrics."""
    row = table.get((seq, "realtime", variant))
    repeats = realtime_repeats(out_dir, seq, folder)
    ates = ([row["ate"]] if row and row["ate"] is not None else []) + [
        m["ate_rmse_m"] for m in repeats
    ]
    return row, ates, repeats


def print_rolling_shutter_medians(out_dir: Path, table: dict, seqs: list[str]) -> None:
    """The global-shutter variant's real-time runs per sequence: median, range, frames lost."""
    lines = []
    for seq in seqs:
        rs, ates, repeats = realtime_runs(
            out_dir, table, seq, "rolling-shutter off", "anchor_rs_repeats"
        )
        if len(ates) > 1:
            lost = (rs["lost"] if rs else 0) + sum(m.get("frames_lost", 0) for m in repeats)
            lines.append(
                f"- {seq}: {median(ates):.4f} m ({min(ates):.4f}-{max(ates):.4f}, "
                f"{len(ates)} runs), {lost} frames lost over the runs"
            )
    if lines:
        print("\nReal time, a global-shutter fit (median, min-max; not the default):")
        print("\n".join(lines))


def load(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def fmt(x, spec="{:.4f}"):
    return "n/a" if x is None else spec.format(x)


def main(out_dir: str) -> int:
    root = Path(out_dir) / "anchor"
    runs = (
        sorted(p for p in root.iterdir() if p.is_dir() and any(v in p.name for v in VARIANTS))
        if root.is_dir()
        else []
    )
    if not runs:
        print("anchor: no runs under", root)
        return 0
    print(
        "\n### Fast motion and the anchor (default local map ORB; restart = new map segment, "
        "accel-gravity = gravity factors from the Kinect's accelerometer; rolling-shutter off = "
        "the colour camera fitted as a global shutter)"
    )
    print(
        "| sequence | mode | variant | ATE m | lost | segments | BA interrupted /100 frames "
        "| dropped |"
    )
    print("|---|---|---|---|---|---|---|---|")
    table = {}
    for run in runs:
        m = load(run / "metrics.json")
        seq = run.name.split("_wait_" if "_wait_" in run.name else "_realtime_")[0]
        mode = "wait" if "_wait_" in run.name else "realtime"
        variant = variant_of(run.name)
        if m is None:
            print(f"| {seq} | {mode} | {variant} | failed | | | | |")
            continue
        frames = max(1, m.get("frames", 1))
        row = {
            "ate": m.get("ate_rmse_m"),
            "lost": m.get("frames_lost", 0),
            "segments": m.get("segments_started", 0),
            "ba": 100.0 * m.get("mapper_ba_interrupted", 0) / frames,
            "dropped": m.get("frontend_dropped", 0),
        }
        table[(seq, mode, variant)] = row
        print(
            f"| {seq} | {mode} | {variant} | {fmt(row['ate'])} | {row['lost']} | "
            f"{row['segments']} | {row['ba']:.1f} | {row['dropped']} |"
        )
    refs = sorted(root.glob("orbslam2_*.json"))
    if refs:
        print("\nORB-SLAM2 (published RGB-D runs, scored here on the same frames):")
        for r in refs:
            s = load(r)
            print(f"- {r.stem}: ATE {fmt(s.get('ate_rmse_m') if s else None)} m")
    seqs = sorted({k[0] for k in table})
    medians = {}
    print("\nReal time, the default run again (median, min-max over the runs):")
    for seq in seqs:
        rt, ates, repeats = realtime_runs(
            Path(out_dir), table, seq, DEFAULT_VARIANT, "anchor_repeats"
        )
        if rt:
            rt["dropped"] += sum(m.get("frontend_dropped", 0) for m in repeats)
            rt["lost"] += sum(m.get("frames_lost", 0) for m in repeats)
        if ates:
            medians[seq] = median(ates)
            print(
                f"- {seq}: {medians[seq]:.4f} m ({min(ates):.4f}-{max(ates):.4f}, {len(ates)} runs)"
            )
    print_rolling_shutter_medians(Path(out_dir), table, seqs)
    print("\nVerdicts (the default: restart on, no accelerometer gravity; real time: the median):")
    status = 0
    for seq in seqs:
        for mode in ("wait", "realtime"):
            row = table.get((seq, mode, DEFAULT_VARIANT))
            if row is None:
                continue
            ok = row["lost"] == 0
            over = " over the runs" if mode == "realtime" else ""
            print(f"- {verdict(ok)} {seq} {mode}: {row['lost']} frames lost{over} (target 0)")
        wait = table.get((seq, "wait", DEFAULT_VARIANT))
        if wait and wait["ate"] and seq in medians:
            ratio = medians[seq] / wait["ate"]
            print(
                f"- {verdict(ratio <= RT_OVER_WAIT_MAX)} {seq}: real time / wait ATE "
                f"{ratio:.3f} (target <= {RT_OVER_WAIT_MAX})"
            )
    xyz = table.get(("fr1_xyz_first300", "realtime", DEFAULT_VARIANT))
    if xyz and "fr1_xyz_first300" in medians:
        ate = medians["fr1_xyz_first300"]
        ok = ate <= XYZ_TARGET_M and xyz["dropped"] == 0
        print(
            f"- {verdict(ok)} fr1_xyz_first300 real time: ATE {ate:.4f} m (median), "
            f"{xyz['dropped']} dropped over the runs (target <= {XYZ_TARGET_M} m, 0 dropped)"
        )
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "out/bench"))
