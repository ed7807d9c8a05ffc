"""longrun.py's verdict on synthetic run folders: keyframes must level off against the exploring
first minute, not merely stay flat between minute 2 and the last one."""

from __future__ import annotations

import csv
import importlib.util
import json
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "longrun", Path(__file__).resolve().parents[1] / "tools" / "longrun.py"
)
longrun = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(longrun)

FPS = 30


def _write_run(folder: Path, new_keyframes_per_minute: list[int], keyframes_end: list[int]) -> Path:
    folder.mkdir(parents=True)
    fields = [
        "index",
        "stamp_s",
        "state",
        "keyframe",
        "frontend_cpu_ms",
        "map_keyframes",
        "map_points",
        "keyframe_wanted",
    ]
    frames, mapping = [], []
    index = 0
    for minute, (new_kf, kf_end) in enumerate(
        zip(new_keyframes_per_minute, keyframes_end, strict=False)
    ):
        n = 60 * FPS
        every = n // new_kf if new_kf else n + 1
        for i in range(n):
            is_kf = new_kf > 0 and i % every == 0 and i // every < new_kf
            frames.append(
                {
                    "index": index,
                    "stamp_s": f"{minute * 60 + i / FPS:.6f}",
                    "state": "tracking",
                    "keyframe": int(is_kf),
                    "frontend_cpu_ms": "10",
                    "map_keyframes": kf_end,
                    "map_points": 2000,
                    "keyframe_wanted": "view_changed" if is_kf else "none",
                }
            )
            if is_kf:
                mapping.append({"keyframe": index, "mapping_ms": "50"})
            index += 1
    with open(folder / "frames.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(frames)
    with open(folder / "mapping.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["keyframe", "mapping_ms"])
        w.writeheader()
        w.writerows(mapping)
    (folder / "rss.csv").write_text("stamp_s,rss_mib\n0,90\n")
    (folder / "metrics.json").write_text(json.dumps({"ate_rmse_m": 0.01, "frames": index}))
    return folder


def test_a_constant_keyframe_rate_is_not_levelling_off(tmp_path, capsys):
    # GIVEN 31 keyframes while exploring, then 27 a minute on revisits (the rate barely falls)
    run = _write_run(tmp_path / "churn", [53, 31, 27], [25, 28, 27])
    # WHEN the table is judged THEN the keyframe check fails (it passed before: 27 <= 31)
    assert longrun.table(run) == 1
    assert "MISSED" in capsys.readouterr().out


def test_keyframes_that_stop_after_exploring_level_off(tmp_path, capsys):
    # GIVEN 53 keyframes while exploring, then 8 and 2 on revisits, the map no larger than after
    # minute 1
    run = _write_run(tmp_path / "steady", [53, 8, 2], [25, 25, 24])
    assert longrun.table(run) == 0
    out = capsys.readouterr().out
    assert "keyframes level off" in out and "met" in out


def test_a_map_that_keeps_growing_does_not_level_off(tmp_path):
    # GIVEN few new keyframes late, but a map that keeps growing past its first-minute size
    run = _write_run(tmp_path / "growing", [53, 8, 2], [25, 30, 34])
    assert longrun.table(run) == 1


def test_one_late_keyframe_after_exploring_still_levels_off(tmp_path, capsys):
    # GIVEN an idle bench run: 64 keyframes while exploring, 4 in minute 2 (one kept),
    # none afterwards - the map stopped one keyframe above its first-minute size
    run = _write_run(tmp_path / "late", [64, 4, 0, 0], [34, 35, 35, 35])
    # THEN it levels off (the size rule has the rate rule's slack, 10 % of minute 1's 64 -> 6)
    assert longrun.table(run) == 0
    assert "(target <= 40): met" in capsys.readouterr().out


def test_a_last_minute_that_maps_nothing_says_so_instead_of_a_ratio(tmp_path, capsys):
    # GIVEN keyframes only while exploring (mapping costs nothing afterwards)
    run = _write_run(tmp_path / "quiet", [47, 0, 0], [32, 32, 32])
    # THEN both checks are met and the cost line names the empty minute, not inf or nan
    assert longrun.table(run) == 0
    out = capsys.readouterr().out
    assert "no keyframe mapped in minute 3" in out
    assert "inf" not in out and "nan" not in out.split("mapping p95")[1]
