"""The soak report: `report.json` (everything), `report.txt` (the readable summary) in the soak's
out folder, and `out/results/soak.json` (scripts/results_write.py's format) for docs/results.md.

Fields of report.json:
  seed, minutes_planned, minutes_flown, interrupted, fatal
  summary         missions flown, outcomes, faults injected per kind, unexpected exits, maps lost,
                  worst hold / waypoint / turn-hold error (truth) and SLAM ATE of the completed
                  missions, worst ATE of any mission, worst camera -> PWM p95, ok
  resources       per process (name and PID): RSS and open descriptors first / last / max and the
                  growth over its life, from /proc/PID/status and /proc/PID/fd
  failures        every mission not "completed" nor "landed by failsafe as expected", with the seed,
                  the mission, the faults injected in it and its recording (MCAP) to replay it
  exits           processes that exited without the soak killing them
  replay          replay-vs-flight ATE of three missions' recordings (soak.replay_check)
  missions        every mission's record (steps, faults, truth, scores)
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

from soak.schedule import FAULT_KINDS

OUTCOMES = ("completed", "landed by failsafe as expected", "aborted (landed safely)", "lost")
# The replay must reproduce the flight's poses within 5 mm RMSE (the recording's purpose: a flight
# replays through SLAM as it flew; docs/recording.md measured 5.7 mm on a HIL flight).
REPLAY_ATE_TARGET_M = 0.005


def _worst(missions, get):
    best = None
    for m in missions:
        for v, where in get(m):
            if v is not None and (best is None or v > best[0]):
                best = (v, where)
    return {"value": best[0], "mission": best[1]} if best else None


def _resources(samples: dict) -> dict:
    out = {}
    for key, series in sorted(samples.items()):
        if not series:
            continue
        rss = [s[1] for s in series]
        fds = [s[2] for s in series if s[2] is not None]
        out[key] = {
            "samples": len(series),
            "from_s": series[0][0],
            "to_s": series[-1][0],
            "rss_mb_first": round(rss[0] / 1024, 1),
            "rss_mb_last": round(rss[-1] / 1024, 1),
            "rss_mb_max": round(max(rss) / 1024, 1),
            "rss_growth_mb": round((rss[-1] - rss[0]) / 1024, 1),
            "fds_first": fds[0] if fds else None,
            "fds_last": fds[-1] if fds else None,
            "fds_max": max(fds) if fds else None,
            "fd_growth": (fds[-1] - fds[0]) if fds else None,
        }
    return out


def build(soak, replays, resources: dict | None = None) -> dict:
    missions = soak.missions
    outcomes = Counter(m.get("outcome", "not judged") for m in missions)
    injected = Counter(f["kind"] for m in missions for f in m.get("faults_injected", []))
    planned_not_injected = sum(
        max(0, len(m["planned_faults"]) - len(m.get("faults_injected", []))) for m in missions
    )
    maps_lost = sum((m.get("slam") or {}).get("new_maps_after_first") or 0 for m in missions)
    # Errors of missions that flew every step: a mission cut short by a failsafe has its last
    # measurement taken while the craft came down (1.7 m below the goal), which says nothing about
    # holding. The cut-short missions are judged by their outcome instead.
    flown = [m for m in missions if m.get("outcome") == "completed"]
    worst_hold = _worst(flown, lambda m: [((m.get("hold") or {}).get("max_m"), m["mission"])])
    worst_wp = _worst(
        flown, lambda m: [(w.get("max_m"), m["mission"]) for w in m.get("waypoints", [])]
    )
    worst_turn = _worst(
        flown,
        lambda m: [((t.get("hold") or {}).get("max_m"), m["mission"]) for t in m.get("turns", [])],
    )
    worst_p95 = _worst(
        missions, lambda m: [((m.get("capture_to_pwm_ms") or {}).get("p95_ms"), m["mission"])]
    )
    worst_ate = _worst(flown, lambda m: [((m.get("ate") or {}).get("ate_rmse_m"), m["mission"])])
    worst_ate_all = _worst(
        missions, lambda m: [((m.get("ate") or {}).get("ate_rmse_m"), m["mission"])]
    )
    failures = [
        {
            "seed": soak.seed,
            "mission": m["mission"],
            "outcome": m.get("outcome"),
            "reason": m.get("reason"),
            "faults": [
                f"{f['kind']} at +{f['mission_s']} s {f['params'] or ''}".strip()
                for f in m.get("faults_injected", [])
            ],
            "recording": m.get("recording"),
            "dir": m["dir"],
            "replay": f"SOAK_SEED={soak.seed} (mission {m['mission']}); "
            + (
                f"python -m flight_recording.replay {m['recording'][0]} --out <dir>"
                if m.get("recording")
                else "no recording"
            ),
        }
        for m in missions
        if m.get("outcome") not in ("completed", "landed by failsafe as expected", "interrupted")
    ]
    # Failsafe landings: how far each drifted from the mission's path with no position source
    # (docs/failsafe.md, "Blind landings"); beyond the fly-away radius is named, not hidden.
    blind = [m for m in missions if m.get("outcome") == "landed by failsafe as expected"]
    worst_blind = _worst(
        blind,
        lambda m: [((m.get("truth") or {}).get("max_distance_from_path_m"), m["mission"])],
    )
    blind_beyond = [
        m["mission"] for m in blind if "blind landing drifted" in (m.get("reason") or "")
    ]
    flown_s = max((m.get("ended_elapsed_s") or 0 for m in missions), default=0)
    replay_ok = replays is None or all(
        (r.get("ate_rmse_m") is not None and r["ate_rmse_m"] <= REPLAY_ATE_TARGET_M)
        for r in replays
    )
    summary = {
        "missions": len(missions),
        "outcomes": {k: outcomes.get(k, 0) for k in OUTCOMES},
        "faults_injected": {k: injected.get(k, 0) for k in FAULT_KINDS},
        "faults_injected_total": sum(injected.values()),
        "faults_planned_not_injected": planned_not_injected,
        "fault_errors": [e for m in missions for e in m.get("fault_errors", [])],
        "unexpected_exits": len(soak.exits),
        "maps_lost": maps_lost,
        "worst_hold_m": worst_hold,
        "worst_waypoint_m": worst_wp,
        "worst_turn_hold_m": worst_turn,
        "worst_capture_to_pwm_p95_ms": worst_p95,
        "worst_failsafe_landing_drift_m": worst_blind,
        "failsafe_landings_beyond_flyaway_radius": blind_beyond,
        "worst_ate_m": worst_ate,
        "worst_ate_any_mission_m": worst_ate_all,
        "ok": not failures and not soak.exits and soak.fatal is None and replay_ok,
    }
    return {
        "seed": soak.seed,
        "minutes_planned": soak.minutes,
        "minutes_flown": round(flown_s / 60, 1),
        "interrupted": soak.interrupted,
        "fatal": soak.fatal,
        "summary": summary,
        "resources": resources if resources is not None else _resources(soak.samples),
        "failures": failures,
        "exits": soak.exits,
        "replay": replays,
        "missions": missions,
    }


def text(rep: dict) -> str:
    s = rep["summary"]
    lines = [
        f"=== soak report: seed {rep['seed']}, {rep['minutes_flown']} of "
        f"{rep['minutes_planned']:g} "
        f"min{' (interrupted)' if rep['interrupted'] else ''}",
        f"missions: {s['missions']}  " + ", ".join(f"{k}: {v}" for k, v in s["outcomes"].items()),
        f"faults injected: {s['faults_injected_total']} ("
        + ", ".join(f"{k} {v}" for k, v in s["faults_injected"].items())
        + f"); planned but not reached: {s['faults_planned_not_injected']}",
        f"unexpected process exits: {s['unexpected_exits']}; maps lost: {s['maps_lost']}",
    ]
    for key, label in (
        ("worst_hold_m", "worst hold error (truth, completed missions)"),
        ("worst_waypoint_m", "worst waypoint error (truth, completed missions)"),
        ("worst_turn_hold_m", "worst hold after a turn (truth, completed missions)"),
        ("worst_ate_m", "worst SLAM ATE (completed missions)"),
        ("worst_ate_any_mission_m", "worst SLAM ATE (any mission)"),
        ("worst_capture_to_pwm_p95_ms", "worst camera -> PWM p95"),
        ("worst_failsafe_landing_drift_m", "worst failsafe landing drift from the path (truth)"),
    ):
        w = s[key]
        lines.append(f"{label}: " + (f"{w['value']} (mission {w['mission']})" if w else "-"))
    if s.get("failsafe_landings_beyond_flyaway_radius"):
        lines.append(
            "failsafe landings that drifted beyond the 2 m fly-away radius (no position source): "
            "missions " + ", ".join(str(n) for n in s["failsafe_landings_beyond_flyaway_radius"])
        )
    lines.append("resources (RSS MB first -> last [max], fds first -> last):")
    for key, r in rep["resources"].items():
        if key.startswith("quad-control") or key.startswith("stress-ng"):
            continue
        lines.append(
            f"  {key}: {r['rss_mb_first']} -> {r['rss_mb_last']} [{r['rss_mb_max']}] MB, "
            f"fds {r['fds_first']} -> {r['fds_last']} over {r['from_s']:.0f}-{r['to_s']:.0f} s"
        )
    qc = [r for k, r in rep["resources"].items() if k.startswith("quad-control")]
    if qc:
        lines.append(
            f"  quad-control ({len(qc)} lives, one per mission): RSS growth per life max "
            f"{max(r['rss_growth_mb'] for r in qc)} MB, last RSS max "
            f"{max(r['rss_mb_last'] for r in qc)} MB, fd growth max "
            f"{max((r['fd_growth'] or 0) for r in qc)}"
        )
    for e in rep["exits"]:
        lines.append(
            f"EXIT {e.get('process')} pid {e.get('pid')} mission {e.get('mission')} "
            f"code {e.get('exit_code')}"
        )
    for f in rep["failures"]:
        lines.append(
            f"FAILURE seed {f['seed']} mission {f['mission']}: {f['outcome']} ({f['reason']}); "
            f"faults: {'; '.join(f['faults']) or 'none'}; "
            f"recording: {(f['recording'] or ['none'])[0]}"
        )
    for r in rep["replay"] or []:
        lines.append(
            f"replay mission {r.get('mission')}: ATE replay vs flight {r.get('ate_rmse_m')} m "
            f"({r.get('frames')} frames given to SLAM in flight of {r.get('frames_recorded')} "
            f"recorded, {len(r.get('recording') or [])} file(s))"
            f"{' ' + r['error'] if r.get('error') else ''}"
        )
    if rep["fatal"]:
        lines.append("FATAL: " + rep["fatal"].splitlines()[0])
    lines.append("verdict: " + ("OK" if s["ok"] else "FINDINGS (see failures / exits / replay)"))
    return "\n".join(lines)


def write(rep: dict, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "report.json").write_text(json.dumps(rep, indent=1, default=str))
    (out / "report.txt").write_text(text(rep) + "\n")
    write_results(rep)


def write_results(rep: dict) -> None:
    """out/results/soak.json for `make results` (scripts/results_write.py's format)."""
    root = Path(__file__).resolve().parents[2]
    sys.path.insert(0, str(root / "scripts"))
    try:
        from results_write import figure, write_result
    finally:
        sys.path.pop(0)
    s = rep["summary"]
    data = f"seed {rep['seed']}, {rep['minutes_flown']} min"
    figs = [
        figure("missions", s["missions"], "", data=data, mode="soak"),
        *[figure(f"outcome: {k}", v, "", data=data, mode="soak") for k, v in s["outcomes"].items()],
        figure("faults injected", s["faults_injected_total"], "", data=data, mode="soak"),
        *[
            figure(f"faults: {k}", v, "", data=data, mode="soak")
            for k, v in s["faults_injected"].items()
        ],
        figure(
            "unexpected process exits", s["unexpected_exits"], "", target=0, data=data, mode="soak"
        ),
        figure("maps lost", s["maps_lost"], "", target=0, data=data, mode="soak"),
    ]
    for key, name, unit in (
        ("worst_hold_m", "worst hold error (completed missions)", "m"),
        ("worst_waypoint_m", "worst waypoint error (completed missions)", "m"),
        ("worst_turn_hold_m", "worst hold after a turn (completed missions)", "m"),
        ("worst_ate_m", "worst SLAM ATE (completed missions)", "m"),
        ("worst_ate_any_mission_m", "worst SLAM ATE (any mission)", "m"),
        ("worst_capture_to_pwm_p95_ms", "worst camera->PWM p95", "ms"),
        ("worst_failsafe_landing_drift_m", "worst failsafe landing drift from the path", "m"),
    ):
        if s.get(key):
            figs.append(figure(name, s[key]["value"], unit, data=data, mode="soak"))
    for key, r in rep["resources"].items():
        name = key.split()[0]
        if name in ("slam-server", "rgbd-streamer", "fw_sim", "kinect-renderer", "soak-runner"):
            figs.append(
                figure(
                    f"{name} RSS growth ({r['from_s']:.0f}-{r['to_s']:.0f} s)",
                    r["rss_growth_mb"],
                    "MB",
                    data=data,
                    mode="soak",
                )
            )
            figs.append(figure(f"{name} fd growth", r["fd_growth"], "", data=data, mode="soak"))
    for r in rep["replay"] or []:
        figs.append(
            figure(
                f"replay ATE mission {r.get('mission')}",
                r.get("ate_rmse_m"),
                "m",
                target=REPLAY_ATE_TARGET_M,
                data=data,
                mode="soak",
            )
        )
    write_result("soak", figs)


def rebuild(out: Path, replays: list[dict] | None = None) -> dict:
    """The report again from a soak's folder (its report.json and every mission.json), with each
    mission judged again by soak.outcome: for a soak flown before a change of the outcome rules.
    replays: the replay check's results (soak.replay_check), else the report's own."""
    from soak.outcome import judge

    old = json.loads((out / "report.json").read_text())
    missions = []
    for path in sorted((out / "missions").glob("mission-*/mission.json")):
        m = json.loads(path.read_text())
        if m.get("outcome") != "interrupted" and "truth" in m:
            m["outcome"], m["reason"] = judge(
                m["truth"],
                m["completed_steps"],
                m["faults_injected"],
                m.get("takeoff_sim_s"),
                (m.get("landing") or {}).get("t_land_sim_s"),
                m.get("gave_up", ""),
            )
            path.write_text(json.dumps(m, indent=1, default=str))
        missions.append(m)
    soak = SimpleNamespace(
        seed=old["seed"],
        minutes=old["minutes_planned"],
        missions=missions,
        exits=old["exits"],
        interrupted=old["interrupted"],
        fatal=old["fatal"],
    )
    return build(
        soak, replays if replays is not None else old["replay"], resources=old["resources"]
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="soak.report",
        description="Rebuild a soak's report (report.json/.txt, out/results/soak.json) from its "
        "folder, judging every mission again with the current outcome rules.",
    )
    ap.add_argument("--rebuild", type=Path, required=True, metavar="DIR", help="the soak's folder")
    args = ap.parse_args(argv)
    if not (args.rebuild / "report.json").is_file():
        print(f"soak.report: {args.rebuild}/report.json not found", file=sys.stderr)
        return 2
    rep = rebuild(args.rebuild)
    write(rep, args.rebuild)
    print(text(rep))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
