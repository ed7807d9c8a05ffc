"""The soak's replay check: three missions' recordings replayed through SLAM with
`flight_recording.replay` (every file of a rotated recording, in order; the frames the flight's
SLAM was given; slam-eval in wait mode, scored against the poses flown), each reported as
replay-vs-flight ATE. Missions are taken in this order: completed missions with faults injected but
no slam-server kill, then other completed ones, then any with a recording; three in all. A
slam-server kill is last because its flight resumed from a map checkpoint that lacks the last
second before the kill, which a replay of the frames cannot reproduce.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from hilrig.paths import find_binary

REPLAYS = 3
# A 2-minute mission is ~3600 frames; extraction and slam-eval in wait mode take a few minutes.
REPLAY_TIMEOUT_S = 1800


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


def replay_missions(missions: list[dict], out: Path, say=print) -> list[dict]:
    results = []
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [
            str(root / "offboard" / "python"),
            str(root / "protocol" / "python"),
            env.get("PYTHONPATH", ""),
        ]
    )
    for m in choose(missions):
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
        try:
            p = subprocess.run(
                cmd, capture_output=True, text=True, timeout=REPLAY_TIMEOUT_S, env=env
            )
        except subprocess.TimeoutExpired:
            results.append({"mission": m["mission"], "ate_rmse_m": None, "error": "timed out"})
            continue
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
                ate_final_trajectory_vs_flight_rmse_m=j.get(
                    "ate_final_trajectory_vs_flight_rmse_m"
                ),
                replay_poses=j.get("replay_poses"),
                flight_poses=j.get("flight_poses"),
                complete=j.get("complete"),
            )
        say(
            f"soak: replay mission {m['mission']}: ATE {r.get('ate_rmse_m')} m "
            f"({r.get('frames')} frames)"
        )
        results.append(r)
    return results
