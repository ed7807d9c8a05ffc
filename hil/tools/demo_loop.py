"""`make demo-loop`: N consecutive `make demo` flights (hil/demo.sh, HIL scenario 2 with SLAM in the
loop), then one summary: how many passed every target, SLAM map resets, camera->PWM latency
range, SLAM ATE range, and the machine's load average around each run (other work on the machine
changes the figures; the report says how busy it was).

    .venv/bin/python hil/tools/demo_loop.py [--runs 10] [--out out/demo-loop] [-- demo args]

Each run's own output stays in <out>/run-NN/ (report.json with its verdict, the processes' logs);
the summary goes to <out>/summary.json. Exit status: 0 when every run passed, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


NO_FLIGHT = "flight (no report: the demo did not fly; see run-NN.log)"


def load_average() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def run_summary(
    index: int, status: int, report: dict | None, load_before: str, load_after: str, wall_s: float
) -> dict:
    """One run's figures from its report.json (None: the demo wrote none)."""
    # No report: the demo did not fly (hil/demo.sh falls back to the SLAM-only demo, exit 3, when a
    # part is missing - e.g. a binary being relinked by a concurrent build): not a pass.
    out = {
        "run": index,
        "exit": status,
        "passed": status == 0 and report is not None,
        "wall_s": round(wall_s, 1),
        "load_before": load_before,
        "load_after": load_after,
    }
    if report is None:
        out["missed"] = [NO_FLIGHT]
        return out
    lat = report.get("latency_ms") or {}
    c2p = lat.get("capture_to_pwm") or {}
    ate = report.get("ate") or {}
    link = report.get("slam_link") or {}
    out.update(
        {
            "missed": [v["target"] for v in report.get("verdict", []) if not v["passed"]],
            "resets": link.get("resets"),
            "link_breaks": link.get("link_breaks"),
            "capture_to_pwm_median_ms": c2p.get("median_ms"),
            "capture_to_pwm_p95_ms": c2p.get("p95_ms"),
            "ate_mm": None if ate.get("ate_rmse_m") is None else round(ate["ate_rmse_m"] * 1000, 1),
            "hold_m": (report.get("hold") or {}).get("max_m"),
            "waypoints_m": [w.get("max_m") for w in report.get("waypoints") or []],
            "touchdown_mps": (report.get("landing") or {}).get("touchdown_vertical_speed_mps"),
            "realtime_factor": report.get("realtime_factor"),
        }
    )
    return out


def _range(values) -> str:
    v = [x for x in values if x is not None]
    return "n/a" if not v else (f"{min(v)}" if min(v) == max(v) else f"{min(v)} .. {max(v)}")


def summarise(runs: list[dict]) -> dict:
    missed: dict[str, int] = {}
    for r in runs:
        for m in r.get("missed", []):
            missed[m] = missed.get(m, 0) + 1
    return {
        "runs": len(runs),
        "passed": sum(r["passed"] for r in runs),
        "resets_total": sum(r.get("resets") or 0 for r in runs),
        "resets_unobserved_runs": sum(r.get("resets") is None for r in runs),
        "capture_to_pwm_median_ms_range": _range(r.get("capture_to_pwm_median_ms") for r in runs),
        "capture_to_pwm_p95_ms_range": _range(r.get("capture_to_pwm_p95_ms") for r in runs),
        "ate_mm_range": _range(r.get("ate_mm") for r in runs),
        "load_average_range": _range(float(r["load_before"].split()[0]) for r in runs),
        "targets_missed": missed,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "demo-loop")
    ap.add_argument("demo_args", nargs="*", help="passed to hil/demo.sh (after --)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    runs = []
    for i in range(1, args.runs + 1):
        run_dir = args.out / f"run-{i:02d}"
        load_before, t0 = load_average(), time.monotonic()
        print(
            f"demo-loop: run {i}/{args.runs} (load average {load_before}) -> {run_dir}", flush=True
        )
        with open(args.out / f"run-{i:02d}.log", "w") as log:
            status = subprocess.call(
                [str(ROOT / "hil" / "demo.sh"), "--out", str(run_dir), *args.demo_args],
                stdout=log,
                stderr=subprocess.STDOUT,
                cwd=ROOT,
            )
        report_path = run_dir / "report.json"
        report = json.loads(report_path.read_text()) if report_path.exists() else None
        r = run_summary(i, status, report, load_before, load_average(), time.monotonic() - t0)
        runs.append(r)
        print(
            f"demo-loop: run {i}: {'PASS' if r['passed'] else 'FAIL (exit %d)' % status}"
            f"{'' if r['passed'] else ' missed ' + ', '.join(r.get('missed', []) or ['?'])}; "
            f"resets {r.get('resets')}, camera->PWM median {r.get('capture_to_pwm_median_ms')} / "
            f"p95 {r.get('capture_to_pwm_p95_ms')} ms, ATE {r.get('ate_mm')} mm, "
            f"hold {r.get('hold_m')} m, "
            f"load {load_before} -> {r['load_after']}",
            flush=True,
        )
        (args.out / "summary.json").write_text(
            json.dumps({"summary": summarise(runs), "runs": runs}, indent=2)
        )
    s = summarise(runs)
    print(
        f"demo-loop: {s['passed']} of {s['runs']} runs passed every target; SLAM map resets "
        f"{s['resets_total']} in total; "
        f"camera->PWM median {s['capture_to_pwm_median_ms_range']} ms, "
        f"p95 {s['capture_to_pwm_p95_ms_range']} ms; ATE {s['ate_mm_range']} mm; "
        "load average (1 min) "
        f"{s['load_average_range']}; misses by target {s['targets_missed'] or 'none'}"
    )
    print(f"demo-loop: summary {args.out / 'summary.json'}")
    return 0 if s["passed"] == s["runs"] else 1


if __name__ == "__main__":
    sys.exit(main())
