"""The soak's replay check: three missions' recordings replayed through SLAM with
`flight_recording.replay` (every file of a rotated recording, in order; the frames the flight's
SLAM was given; slam-eval held to the lock schedule slam-server recorded for the mission's map, or
in wait mode when the mission has none or more than one map; scored against the poses flown), each
reported as replay-vs-flight ATE. Missions are taken in this order: completed missions with
faults injected but no slam-server kill, then other completed ones, then any with a recording;
three in all. A slam-server kill is last because its flight resumed from a map checkpoint that
lacks the last second before the kill, which a replay of the frames cannot reproduce.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from hilrig.paths import find_binary

REPLAYS = 3
# slam-server's name for it in each map's tables folder (slamlink kLockScheduleFile).
LOCK_SCHEDULE_FILE = "lock_schedule.txt"
# A 2-minute mission is ~3600 frames; extraction and slam-eval in wait mode take a few minutes.
REPLAY_TIMEOUT_S = 1800
# Two replays at a time: the machine's two cores, the flights being over. Each replay is one
# Python extraction (single-threaded) and then slam-eval, so two keep both cores busy.
REPLAY_WORKERS = 2


def choose(missions: list[dict], count: int = REPLAYS) -> list[dict]:
    with_rec = [m for m in missions if m.get("recording")]
    completed = [m for m in with_rec if m.get("outcome") == "completed"]
    faulted = [
        m
        for m in completed
        if m.get("faults_injected")
        and not any(f["kind"] == "slam_server_kill" for f in m["faults_injected"])
    ]
    chosen: list[dict] = []
    for group in (faulted, completed, with_rec):
        for m in group:
            if len(chosen) < count and m not in chosen:
                chosen.append(m)
    return chosen


def lock_schedule_of(m: dict) -> Path | None:
    """The lock schedule of the mission's one SLAM map (a mission whose slam-server was restarted
    flew on several maps, the later ones resumed from a checkpoint: no single record covers it)."""
    maps = m.get("slam_maps") or []
    if len(maps) != 1:
        return None
    path = Path(maps[0]) / LOCK_SCHEDULE_FILE
    return path if path.is_file() else None


def _replay_one(m: dict, out: Path, env: dict, say) -> dict:
    mcaps = m["recording"]
    d = out / f"mission-{m['mission']:03d}"
    say(f"soak: replay check, mission {m['mission']} ({len(mcaps)} file(s)) -> {d}")
    t0 = time.monotonic()
    cmd = [
        sys.executable,
        "-m",
        "flight_recording.replay",
        *mcaps,
        "--out",
        str(d),
        "--slam-eval",
        str(find_binary("slam-eval")),
        "--tum-score",
        str(find_binary("tum-score")),
    ]
    schedule = lock_schedule_of(m)
    if schedule is not None:
        cmd += ["--lock-schedule", str(schedule)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=REPLAY_TIMEOUT_S, env=env)
    except subprocess.TimeoutExpired:
        return {"mission": m["mission"], "ate_rmse_m": None, "error": "timed out"}
    r = {"mission": m["mission"], "recording": mcaps, "wall_s": round(time.monotonic() - t0)}
    if p.returncode != 0:
        r.update(ate_rmse_m=None, error=(p.stderr or p.stdout)[-500:])
    else:
        j = json.loads((d / "replay.json").read_text())
        r.update(
            ate_rmse_m=j.get("ate_replay_vs_flight_rmse_m"),
            ate_max_m=j.get("ate_replay_vs_flight_max_m"),
            frames=j.get("frames"),
            frames_recorded=j.get("frames_recorded"),
            ate_final_trajectory_vs_flight_rmse_m=j.get("ate_final_trajectory_vs_flight_rmse_m"),
            replay_poses=j.get("replay_poses"),
            flight_poses=j.get("flight_poses"),
            complete=j.get("complete"),
            lock_schedule=j.get("lock_schedule"),
        )
    say(
        f"soak: replay mission {m['mission']}: ATE {r.get('ate_rmse_m')} m "
        f"({r.get('frames')} frames, {r['wall_s'] if 'wall_s' in r else '-'} s)"
    )
    return r


def replay_missions(missions: list[dict], out: Path, say=print) -> list[dict]:
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [
            str(root / "offboard" / "recorder"),
            str(root / "protocol" / "python"),
            env.get("PYTHONPATH", ""),
        ]
    )
    chosen = choose(missions)
    with ThreadPoolExecutor(max_workers=REPLAY_WORKERS) as pool:
        return list(pool.map(lambda m: _replay_one(m, out, env, say), chosen))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="soak.replay_check",
        description="The replay check of a soak already flown (e.g. with --no-replay): replays "
        "three of its missions' recordings and rewrites its report (report.json/.txt, "
        "out/results/soak.json) with the results.",
    )
    ap.add_argument("soak_dir", type=Path, help="the soak's folder (its report.json)")
    args = ap.parse_args(argv)
    if not (args.soak_dir / "report.json").is_file():
        print(f"soak.replay_check: {args.soak_dir}/report.json not found", file=sys.stderr)
        return 2
    if find_binary("slam-eval") is None or find_binary("tum-score") is None:
        print(
            "soak.replay_check: slam-eval / tum-score not built (RGBD_BUILD_DIR)", file=sys.stderr
        )
        return 3
    from soak import report

    missions = json.loads((args.soak_dir / "report.json").read_text())["missions"]
    replays = replay_missions(missions, args.soak_dir / "replay")
    rep = report.rebuild(args.soak_dir, replays=replays)
    report.write(rep, args.soak_dir)
    print(report.text(rep))
    return 0 if rep["summary"]["ok"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
