#!/usr/bin/env python3
"""Prints the SLAM benchmark tables from the metrics.json files that offboard/bench/bench.sh wrote.

Layout: OUT/<sequence>/<features>_<backend>/metrics.json, OUT/<sequence>/peer/metrics.json,
OUT/realtime_orb/metrics.json. Tables follow thesis Table 4.8 (RPE, frame to frame) and
Table 4.10 (ATE RMSE): one row per detector, one column per back-end (VO, VO+LLC, VO+GLC).
Standard library only.
"""

import json
import sys
from pathlib import Path

DETECTORS = ["sift", "surf", "orb"]
BACKENDS = [("localmap", "local map"), ("vo", "VO"), ("llc", "VO+LLC"), ("glc", "VO+GLC")]


def load(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def cell(m, key, fmt):
    if m is None or key not in m:
        return "n/a"
    return fmt.format(m[key])


def stage(m, name, key="median_ms"):
    try:
        return m["stages"][name][key]
    except (KeyError, TypeError):
        return None


def main(out_dir: str) -> int:  # noqa: C901 (one printer per table, in the order printed)
    out = Path(out_dir)
    special = ("realtime_", "longrun", "reloc", "loop_", "rate_")
    seqs = sorted(p.name for p in out.iterdir() if p.is_dir() and not p.name.startswith(special))
    for seq in seqs:
        runs = {
            (d, b): load(out / seq / f"{d}_{b}" / "metrics.json")
            for d in DETECTORS
            for b, _ in BACKENDS
        }
        peer = load(out / seq / "peer" / "metrics.json")
        print(f"\n### {seq}")
        print("\nTable 4.8 shape - RPE frame-to-frame, translation RMSE mm / rotation RMSE deg")
        print("| detector | " + " | ".join(h for _, h in BACKENDS) + " |")
        print("|---|" + "---|" * len(BACKENDS))
        for d in DETECTORS:
            cells = [
                f"{cell(runs[d, b], 'rpe_trans_rmse_mm', '{:.2f}')} / "
                f"{cell(runs[d, b], 'rpe_rot_rmse_deg', '{:.3f}')}"
                for b, _ in BACKENDS
            ]
            print(f"| {d.upper()} | " + " | ".join(cells) + " |")
        print("\nTable 4.10 shape - ATE translation RMSE m (rotation RMSE deg)")
        print("| detector | " + " | ".join(h for _, h in BACKENDS) + " |")
        print("|---|" + "---|" * len(BACKENDS))
        for d in DETECTORS:
            cells = [
                f"{cell(runs[d, b], 'ate_rmse_m', '{:.4f}')} "
                f"({cell(runs[d, b], 'ate_rot_rmse_deg', '{:.2f}')})"
                for b, _ in BACKENDS
            ]
            print(f"| {d.upper()} | " + " | ".join(cells) + " |")
        print(
            "\nPer-stage median ms (wall clock; frontend_cpu = CPU ms of the front-end thread, "
            "OpenCV single-threaded)"
        )
        names = [
            "features",
            "matching",
            "ransac",
            "frontend",
            "frontend_cpu",
            "keyframe",
            "llc",
            "glc",
            "posegraph",
            "backend",
        ]
        print("| run | keyframes | loops | " + " | ".join(names) + " |")
        print("|---|---|---|" + "---|" * len(names))
        for d in DETECTORS:
            for b, _ in BACKENDS:
                m = runs[d, b]
                if m is None:
                    continue
                vals = []
                for n in names:
                    v = stage(m, n)
                    vals.append("-" if v is None else f"{v:.1f}")
                print(
                    f"| {d}_{b} | {m.get('keyframes', '?')} | {m.get('loop_closures', '?')} | "
                    + " | ".join(vals)
                    + " |"
                )
        if peer is not None:
            print(
                f"\nPeer cv::rgbd::RgbdOdometry: ATE {cell(peer, 'ate_rmse_m', '{:.4f}')} m, "
                f"RPE {cell(peer, 'rpe_trans_rmse_mm', '{:.2f}')} mm / "
                f"{cell(peer, 'rpe_rot_rmse_deg', '{:.3f}')} deg, "
                f"{cell(peer, 'ms_per_frame_median', '{:.1f}')} ms/frame median wall, "
                f"{cell(peer, 'cpu_ms_per_frame_median', '{:.1f}')} ms CPU"
            )
            for d, b in [(d, b) for d in DETECTORS for b in ("localmap", "glc")]:
                m = runs[d, b]
                if m is None or "ate_rmse_m" not in m or "ate_rmse_m" not in peer:
                    continue
                fe = stage(m, "frontend")
                pm = peer.get("ms_per_frame_median")
                fc = stage(m, "frontend_cpu")
                pc = peer.get("cpu_ms_per_frame_median")
                ratio_t = f"{fe / pm:.2f}" if fe and pm else "n/a"
                ratio_c = f"{fc / pc:.2f}" if fc and pc else "n/a"
                print(
                    f"  {d.upper()} {dict(BACKENDS)[b]} vs peer: "
                    f"ATE ratio {m['ate_rmse_m'] / peer['ate_rmse_m']:.2f}, "
                    f"front-end ms ratio {ratio_t} (wall), {ratio_c} (CPU)"
                )
    rts = sorted(p for p in out.iterdir() if p.is_dir() and p.name.startswith("realtime_"))
    if rts:
        print(
            "\n### Real-time replay (30 fps pacing, fr1_xyz_first300; "
            "wall ms depend on the machine's load)"
        )
        print(
            "| run | frames | front-end dropped | back-end skipped | ATE m | RPE mm | "
            "tracking CPU median / p95 ms | "
            "front-end wall median / p95 ms | mapping CPU p95 ms | map-lock wait p95 / max ms |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for p in rts:
            rt = load(p / "metrics.json")
            if rt is None:
                continue
            mp = (rt.get("mapping") or {}).get("mapping_cpu") or {}
            print(
                f"| {p.name[len('realtime_') :]} | {rt.get('frames_submitted')} | "
                f"{rt.get('frontend_dropped')} | "
                f"{rt.get('backend_skipped')} | {cell(rt, 'ate_rmse_m', '{:.4f}')} | "
                f"{cell(rt, 'rpe_trans_rmse_mm', '{:.2f}')} | "
                f"{stage(rt, 'frontend_cpu') or float('nan'):.1f} / "
                f"{stage(rt, 'frontend_cpu', 'p95_ms') or float('nan'):.1f} | "
                f"{stage(rt, 'frontend') or float('nan'):.1f} / "
                f"{stage(rt, 'frontend', 'p95_ms') or float('nan'):.1f} | "
                f"{mp.get('p95_ms', float('nan')):.1f} | "
                f"{stage(rt, 'map_lock_wait', 'p95_ms') or float('nan'):.2f} / "
                f"{stage(rt, 'map_lock_wait', 'max_ms') or float('nan'):.1f} |"
            )
    loops = sorted(p for p in out.iterdir() if p.is_dir() and p.name.startswith("loop_"))
    if loops:
        print(
            "\n### Loop closing on vs off (local map ORB; "
            "lock = map-lock hold of the correction step, "
            "fuse = longest hold of one fusion step)"
        )
        print(
            "| run | ATE m | RPE mm | keyframes | loop searches | detections | RANSAC-verified | "
            "accepted | "
            "loop closing CPU p95 ms | snapshot lock ms p95 / max | pose graph ms max | "
            "lock ms max | fuse ms max | "
            "BA dropped | dropped |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for p in loops:
            m = load(p / "metrics.json")
            if m is None:
                continue
            lc = m.get("loop_closing") or {}

            def mx(key, lc=lc):
                v = lc.get(key) or {}
                return f"{v['p95_ms']:.1f}" if "p95_ms" in v else "-"

            print(
                f"| {p.name[len('loop_') :]} | {cell(m, 'ate_rmse_m', '{:.4f}')} | "
                f"{cell(m, 'rpe_trans_rmse_mm', '{:.2f}')} | "
                f"{m.get('keyframes')} | {lc.get('keyframes_searched', '-')} | "
                f"{lc.get('detections', '-')} | "
                f"{lc.get('ransac_verified', '-')} | {lc.get('accepted', '-')} | "
                f"{mx('loop_closing_cpu')} | "
                f"{mx('snapshot_lock')} / "
                f"{(lc.get('snapshot_lock') or {}).get('max_ms', float('nan')):.1f} | "
                f"{(lc.get('posegraph') or {}).get('max_ms', '-')} | "
                f"{(lc.get('apply_lock') or {}).get('max_ms', '-')} | "
                f"{(lc.get('fuse_lock_max_per_keyframe') or {}).get('max_ms', '-')} | "
                f"{lc.get('local_ba_discarded', '-')} | "
                f"{m.get('frontend_dropped')} |"
            )
    rates = sorted(
        {
            int(p.name.split("_")[1])
            for p in out.iterdir()
            if p.is_dir() and p.name.startswith("rate_")
        }
    )
    if rates:
        print(
            "\n### Larger steps between frames (local map ORB, wait, "
            "fr1_xyz_first300 every k-th frame): "
            "cross-check of weak fits on / off"
        )
        print(
            "| k (fps) | ATE m on / off | RPE mm on / off | keyframes on / off | "
            "cross-checks (replaced) | "
            "lost frames on / off | tracking CPU p95 ms on / off |"
        )
        print("|---|---|---|---|---|---|---|")
        for k in rates:
            on, off = (load(out / f"rate_{k}_cc_{c}" / "metrics.json") or {} for c in ("on", "off"))
            print(
                f"| {k} ({30 / k:.1f}) | "
                f"{cell(on, 'ate_rmse_m', '{:.4f}')} / {cell(off, 'ate_rmse_m', '{:.4f}')} | "
                f"{cell(on, 'rpe_trans_rmse_mm', '{:.2f}')} / "
                f"{cell(off, 'rpe_trans_rmse_mm', '{:.2f}')} | "
                f"{on.get('keyframes', '-')} / {off.get('keyframes', '-')} | "
                f"{on.get('cross_checks', '-')} ({on.get('cross_check_replacements', '-')}) | "
                f"{on.get('tracking_lost_frames', '-')} / {off.get('tracking_lost_frames', '-')} | "
                f"{stage(on, 'frontend_cpu', 'p95_ms') or float('nan'):.1f} / "
                f"{stage(off, 'frontend_cpu', 'p95_ms') or float('nan'):.1f} |"
            )
    for name, title in (
        ("reloc_gap", "1 s of frames withheld mid-sequence"),
        ("reloc_reload", "second run started from the reloaded map"),
    ):
        m = load(out / name / "metrics.json")
        if m is not None:
            print(
                f"\nRelocalisation, {title}: frames until tracking after the gap/start "
                f"{m.get('frames_until_tracking_after_gap', m.get('frames_until_first_tracked'))}, "
                f"relocalisations {m.get('relocalisations')}, "
                f"lost frames {m.get('tracking_lost_frames')}, "
                f"ATE {cell(m, 'ate_rmse_m', '{:.4f}')} m"
            )
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: bench_table.py OUT_DIR", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
