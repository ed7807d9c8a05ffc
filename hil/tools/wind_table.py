"""The wind table: how well the closed loop (SLAM in the loop, HIL scenario 1's hold) holds against
gust strength, for each of quad-control's position laws, up to the level where the loop fails.

    .venv/bin/python hil/tools/wind_table.py [--gusts 0,0.15,0.3,0.5,0.8,1.2] [--laws cascade,pid]
        [--hold-s 30] [--fail-bound-m 0.5] [--out out/wind] [--results-dir out/results]

Each flight is a hilrig.slam_flight.SlamFlight (every board its emulator, every program the real
one; it takes the machine-wide HIL flight lock, so it may wait for another flight): take off, hold
1.7 m for --hold-s after the 5 s settling, scored on the FC emulator's truth. The gusts are the
FC emulator's Gauss-Markov air currents (QuadParams.gust_accel_std_mss, 2 s correlation) with
scenario 1's trim error (0.5 / -0.3 deg) and disturbance seed. The gust levels are flown in
increasing order, every law at each level, until the loop fails for a law - the hold exceeds
--fail-bound-m, tracking was lost for good (quad-control no longer in hold at the end), a failsafe
fired, or the mission could not go on - and stronger levels are not flown for that law. SLAM
frames lost are reported either way.

Per flight: hold max / rms (truth), the share of commands with roll or pitch at quad-control's lean
limit (attitude authority), SLAM frames lost and ATE, camera -> PWM latency, the machine's load.
Writes <out>/<law>-g<gust>.json per flight, <out>/table.md, and <results-dir>/wind.json (kind
"wind", the format scripts/results.py puts on docs/results.md with `make results`).
Exit status: 0 when the table was made (a failing level is a result, not an error), 2 on bad
arguments or when the HIL parts are not built.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
for sub in (
    "hil",
    "protocol/python",
    "offboard/quadcontrol",
    "offboard/recorder",
    "offboard/study",
    "firmware/tools",
    "scripts",
):
    if str(ROOT / sub) not in sys.path:
        sys.path.insert(0, str(ROOT / sub))

LAWS = ("cascade", "pid")  # quad-control controller.position_law values
DEFAULT_GUSTS_MSS = (0.0, 0.15, 0.3, 0.5, 0.8, 1.2)
HOLD_TARGET_M = 0.15  # scenario 1's target
# Beyond this the loop has failed as a position hold: a third of the 3 m between the take-off point
# and the nearest obstacle in the HIL room, and 3x the target.
DEFAULT_FAIL_BOUND_M = 0.5
# Scenario 1's disturbances besides the gust strength (test_scenario_slam_closed_loop.DISTURBED).
GUST_TAU_S = 2.0
TRIM_ERROR_DEG = (0.5, -0.3)
DISTURBANCE_SEED = 7
# quad-control's lean limit as a pulse: roll/pitch output_limit_pct 20 % of the 480 us beyond the
# APM's 20 us stick dead zone, plus the dead zone (core/stick_mapping.hpp centred_to_us).
APM_STICK_DEADZONE_US = 20.0
LEAN_LIMIT_PCT = 20.0
STICK_SPAN_US = 500.0
LEAN_LIMIT_OFFSET_US = APM_STICK_DEADZONE_US + LEAN_LIMIT_PCT / 100.0 * (
    STICK_SPAN_US - APM_STICK_DEADZONE_US
)
NEUTRAL_US = 1500


def parse_gusts(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"not a list of numbers: {text!r}") from e
    if not values or any(not math.isfinite(v) or v < 0 or v > 5 for v in values):
        raise argparse.ArgumentTypeError("values in m/s^2, each in [0, 5]")
    return sorted(set(values))


def parse_laws(text: str) -> list[str]:
    laws = [v.strip() for v in text.split(",") if v.strip()]
    bad = [v for v in laws if v not in LAWS]
    if not laws or bad:
        raise argparse.ArgumentTypeError(f"choose from {','.join(LAWS)}; not {bad or text!r}")
    return laws


def saturated_share(commands: list[dict], from_us: int) -> float | None:
    """Share of the commands sent in hold since `from_us` (quad-control's clock) whose roll or
    pitch pulse sits at the lean limit."""
    rows = [c for c in commands if c.get("state") == "hold" and int(c["send_us"]) >= from_us]
    if not rows:
        return None
    limit = LEAN_LIMIT_OFFSET_US - 1.0  # rounding to whole microseconds
    at = sum(
        1
        for c in rows
        if abs(int(c["roll_us"]) - NEUTRAL_US) >= limit
        or abs(int(c["pitch_us"]) - NEUTRAL_US) >= limit
    )
    return round(at / len(rows), 3)


def fly_one(law: str, gust: float, hold_s: float, workdir: Path) -> dict:
    """One take-off and hold at this gust strength with this law; the figures of the flight."""
    from fc_emulator import QuadParams
    from hilrig import missions
    from hilrig.slam_flight import HIL_CONTROLLER_GAINS, SlamFlight, SlamFlightOptions

    params = QuadParams(
        gust_accel_std_mss=gust,
        gust_tau_s=GUST_TAU_S,
        trim_error_deg=TRIM_ERROR_DEG,
        disturbance_seed=DISTURBANCE_SEED,
    )
    overrides = {**HIL_CONTROLLER_GAINS, "position_law": law}
    out: dict = {"law": law, "gust_mss": gust, "hold_s": hold_s}
    t0 = time.monotonic()
    with SlamFlight(
        workdir, SlamFlightOptions(quad_params=params, controller_overrides=overrides)
    ) as f:
        try:
            to = missions.take_off(f, progress=print)
            # Scored like the hold: from missions.SETTLE_S after quad-control reported "hold"
            # (commands.csv's send_us is CLOCK_MONOTONIC, as time.monotonic_ns()).
            t_hold_wall_us = time.monotonic_ns() // 1000 + int(missions.SETTLE_S * 1e6)
            out["hold"] = missions.hold(f, to["start_room_m"], hold_s, progress=print)
            out["state_after"] = f.state()["state"]
            out["lean_limit_share"] = saturated_share(f.commands(), t_hold_wall_us)
        except (TimeoutError, RuntimeError) as e:  # the mission could not go on: a failure level
            out["aborted"] = str(e)[:300]
        out["failsafe_events"] = [e for _, e in f.rig.fc.events if "failsafe" in e]
        out["realtime_factor"] = round(f.rig.realtime_factor, 3)
        out.update(f.scores())
    out["wall_s"] = round(time.monotonic() - t0, 1)
    return out


def failure(flight: dict, bound_m: float) -> str | None:
    """Why this flight counts as the loop failing (None: it held)."""
    if flight.get("aborted"):
        return "mission aborted: " + flight["aborted"][:120]
    if flight.get("failsafe_events"):
        return "failsafe"
    if flight.get("state_after") != "hold":
        return f"left hold ({flight.get('state_after')})"
    if flight["hold"].get("max_m", math.inf) > bound_m:
        return f"hold {flight['hold']['max_m']} m > {bound_m} m"
    return None


def figures(flights: list[dict], hold_s: float) -> list[dict]:
    """Result-file figures (scripts/results_write.py format), one group per flight."""
    from results_write import figure

    figs = []
    for f in flights:
        data = f"gust {f['gust_mss']:g} m/s^2, hold {hold_s:g} s"
        hold = f.get("hold") or {}
        lat = (f.get("latency_ms") or {}).get("capture_to_pwm") or {}
        figs += [
            figure(
                "hold max", hold.get("max_m"), "m", target=HOLD_TARGET_M, data=data, mode=f["law"]
            ),
            figure("hold rms", hold.get("rms_m"), "m", data=data, mode=f["law"]),
            figure(
                "at the lean limit", f.get("lean_limit_share"), "share", data=data, mode=f["law"]
            ),
            figure(
                "SLAM ATE", (f.get("ate") or {}).get("ate_rmse_m"), "m", data=data, mode=f["law"]
            ),
            figure("camera->PWM p95", lat.get("p95_ms"), "ms", data=data, mode=f["law"]),
        ]
        if f.get("failure"):
            figs.append(figure("loop failed: " + f["failure"], None, "", data=data, mode=f["law"]))
    return figs


def markdown(flights: list[dict]) -> str:
    lines = [
        "| law | gust m/s^2 | hold max m | hold rms m | at lean limit | SLAM lost | ATE mm | "
        "camera->PWM p95 ms | load | outcome |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for f in flights:
        hold = f.get("hold") or {}
        ate = (f.get("ate") or {}).get("ate_rmse_m")
        lat = ((f.get("latency_ms") or {}).get("capture_to_pwm") or {}).get("p95_ms")
        cells = [
            f["law"],
            f"{f['gust_mss']:g}",
            hold.get("max_m", "-"),
            hold.get("rms_m", "-"),
            f.get("lean_limit_share", "-"),
            (f.get("slam_tracking") or {}).get("lost", "-"),
            round(ate * 1000, 1) if ate is not None else "-",
            lat if lat is not None else "-",
            f.get("load_average", "-"),
            f.get("failure") or "held",
        ]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"


def write_outputs(flights: list[dict], args) -> None:
    """<out>/table.md and <results-dir>/wind.json from the flights so far."""
    from results_write import make_result

    (args.out / "table.md").write_text(markdown(flights))
    record = make_result("wind", figures(flights, args.hold_s))
    record["note"] = (
        "Hold error (FC emulator truth) against gust strength (Gauss-Markov, 2 s correlation, "
        f"trim {TRIM_ERROR_DEG[0]} / {TRIM_ERROR_DEG[1]} deg, seed {DISTURBANCE_SEED}), "
        f"HIL scenario 1 with SLAM in the loop, hold {args.hold_s:g} s after 5 s settling; "
        "mode = quad-control's position law (cascade: the default; pid: the thesis). "
        "Levels above a law's first failure were not flown (hil/tools/wind_table.py, docs/hil.md)."
    )
    (args.results_dir / "wind.json").write_text(json.dumps(record, indent=2) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="Hold error against gust strength for each position law (HIL flights).",
        epilog="Each flight takes the machine-wide HIL flight lock (it may wait for another).",
    )
    ap.add_argument(
        "--gusts",
        type=parse_gusts,
        default=list(DEFAULT_GUSTS_MSS),
        help="gust strengths (std, m/s^2), comma-separated (default %(default)s)",
    )
    ap.add_argument(
        "--laws",
        type=parse_laws,
        default=list(LAWS),
        help="position laws, comma-separated: cascade (default law), pid (thesis)",
    )
    ap.add_argument("--hold-s", type=float, default=30.0, help="scored hold per flight (s)")
    ap.add_argument(
        "--fail-bound-m",
        type=float,
        default=DEFAULT_FAIL_BOUND_M,
        help="a hold beyond this counts as the loop failing (m)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=ROOT / "out" / "wind",
        help="flight reports, work folders and table.md",
    )
    ap.add_argument(
        "--results-dir",
        type=Path,
        default=ROOT / "out" / "results",
        help="where wind.json goes (scripts/results.py reads it)",
    )
    args = ap.parse_args(argv)
    if not (math.isfinite(args.hold_s) and 5.0 <= args.hold_s <= 600.0):
        ap.error("--hold-s must be in [5, 600]")
    if not (math.isfinite(args.fail_bound_m) and args.fail_bound_m > HOLD_TARGET_M):
        ap.error(f"--fail-bound-m must be above the {HOLD_TARGET_M} m target")

    from hilrig.slam_flight import missing_parts

    missing = missing_parts()
    if missing:
        print("wind_table: not built / not installed: " + ", ".join(missing), file=sys.stderr)
        return 2

    args.out.mkdir(parents=True, exist_ok=True)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    flights: list[dict] = []
    failed: set[str] = set()
    # Gust level by gust level, both laws at each, so an interrupted run still compares them.
    for gust in args.gusts:
        for law in args.laws:
            if law in failed:
                continue  # stronger gusts are not flown for a law that failed
            name = f"{law}-g{gust:g}"
            print(f"wind_table: {name}", flush=True)
            f = fly_one(law, gust, args.hold_s, args.out / name)
            f["failure"] = failure(f, args.fail_bound_m)
            (args.out / f"{name}.json").write_text(json.dumps(f, indent=2, default=str))
            flights.append(f)
            print(f"wind_table: {name}: hold {f.get('hold')}, {f['failure'] or 'held'}", flush=True)
            # The table and the result file after every flight: an interrupted run keeps what it
            # flew.
            write_outputs(flights, args)
            if f["failure"]:
                failed.add(law)
    print((args.out / "table.md").read_text())
    print(f"wind_table: {args.results_dir / 'wind.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
