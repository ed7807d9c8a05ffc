"""Tolerant reading of slam-eval's metrics.json: the study needs keyframes, loop closures, frames
and per-stage times, wherever in the JSON tree the engine puts them.

Rules (documented in docs/study.md): the JSON is flattened to dotted paths; a count is the first
integer whose last path element contains the word (e.g. "keyframes", "loop_closures"); a stage is
any object holding a mean/median/p95 number (keys containing "mean", "median", "p95"), named by
its own key. Missing values come back as None; a malformed file as an empty dict.
"""

from __future__ import annotations

import json
from pathlib import Path


def load(path: str | Path) -> dict:
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def flatten(tree, prefix: str = "") -> dict[str, object]:
    out: dict[str, object] = {}
    if isinstance(tree, dict):
        for key, value in tree.items():
            out.update(flatten(value, f"{prefix}{key}."))
    else:
        out[prefix[:-1]] = tree
    return out


def count(metrics: dict, word: str) -> int | None:
    for path, value in flatten(metrics).items():
        last = path.rsplit(".", 1)[-1].lower()
        if word in last and isinstance(value, (int, float)) and not isinstance(value, bool):
            if "time" in last or "ms" in last or "rate" in last:
                continue
            return int(value)
    return None


def stages(metrics: dict) -> dict[str, dict[str, float]]:
    """{stage: {"mean_ms":, "median_ms":, "p95_ms":}} for every timing object found."""
    found: dict[str, dict[str, float]] = {}

    def walk(node, name: str) -> None:
        if not isinstance(node, dict):
            return
        stats = {}
        for key, value in node.items():
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                low = key.lower()
                for stat in ("median", "mean", "p95"):
                    if stat in low:
                        stats.setdefault(f"{stat}_ms", float(value))
        if stats and name:
            found[name] = stats
        for key, value in node.items():
            walk(value, key)

    walk(metrics, "")
    return found
