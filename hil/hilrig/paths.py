"""Where the scenarios find the repository, the build outputs and where they write their reports.

RGBD_BUILD_DIR selects the build folder (default: <repo>/build, what `make build` produces).
Reports go to <repo>/test-artifacts/hil/ (git-ignored).
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def build_dir() -> Path:
    return Path(os.environ.get("RGBD_BUILD_DIR", REPO_ROOT / "build"))


def find_binary(name: str) -> Path | None:
    """<build>/bin/<name> if it exists and is executable, else None."""
    p = build_dir() / "bin" / name
    return p if p.is_file() and os.access(p, os.X_OK) else None


def artifacts_dir() -> Path:
    d = REPO_ROOT / "test-artifacts" / "hil"
    d.mkdir(parents=True, exist_ok=True)
    return d
