"""What the contract generators share (protocol/camera/tools/gen_tum_cameras.py,
protocol/control/tools/gen_control.py): formatting a generated header in the repository's C++ style
and the write / --check command line. Standard library and clang-format."""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Callable


def clang_format(text: str, path: Path, tool: str) -> str:
    """The repository's C++ style (.clang-format, found from `path`'s folder), so generated headers
    pass scripts/lint.sh. `tool` names the generator in the error when clang-format is missing."""
    exe = shutil.which("clang-format")
    if exe is None:
        raise SystemExit(f"{tool}: clang-format not found (make deps installs it)")
    return subprocess.run(
        [exe, f"--assume-filename={path}"],
        input=text,
        capture_output=True,
        text=True,
        check=True,
        cwd=path.parent,
    ).stdout


def main(description: str, outputs: Callable[[], dict[Path, str]], regenerate: str) -> int:
    """Writes every generated file, or with --check exits 1 naming each committed file that differs
    from what the spec generates (`regenerate`: the command that fixes it)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(
        "--check",
        action="store_true",
        help="exit 1 if a committed file differs from what the spec generates",
    )
    args = parser.parse_args()
    stale = []
    for path, text in outputs().items():
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(path)
        else:
            path.write_text(text)
            print(f"wrote {path}")
    for path in stale:
        print(f"{path} is stale: run {regenerate}", file=sys.stderr)
    return 1 if stale else 0
