#!/usr/bin/env python3
"""Flag words that narrate the project's history instead of describing the system.

The repository is reference documentation of the system as it is: comments say why the code is as it
is, docs say what a component is and how it behaves, and dated figures live in docs/results.md only.
This check scans every tracked text file (`git ls-files`) and prints `path:line: text` for each line
that refers to a work period, a tracker entry or a person; it exits 1 if there is any such line.

Rules (case-insensitive):

* every file: a numbered work period (`session` or `sessions` followed by a number in any base,
  `0x2a` included), a tracker entry (`issue` followed by a number, with or without `#`), and the
  word lead after the definite article. The word session alone is fine (a streaming handshake, an
  HTTP connection); a SLAM map and its lifetime are called a map, so a map's id follows `map`
  (`map 000000000000002a resumed`) and never `session`. An option or identifier ending in
  `-sessions`/`_session` followed by a value (`--max-sessions 4`) is not a work period and is not
  flagged.
* prose only (docs/*.md and the top-level README.md): the words lead(s) and helper(s) in any use
  except the verb phrase "lead(s) to". Prose names a thing by what it is ("test support code",
  "the scoring functions"), so both words there can only mean a person. In code and code comments
  "helper" is a legitimate word for a function or a class and is not checked.

Skipped: files git does not track, binary files (a NUL byte in the first 8 KiB, or the extensions
below) and third-party or generated data (the TUM RGB-D excerpts in tests/data/, the fuzz and
vector corpora).

Usage: scripts/check_history_words.py [--root DIR] [--pending DIR ...]
  --root     the repository to scan (default: the one holding this script)
  --pending  a folder whose hits are printed but do not fail the check (a folder being rewritten;
             scripts/lint.sh names them until they are clean)
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

EVERYWHERE = re.compile(
    r"(?<![-_])\bsessions?\s+[0-9]|\bissues?\s+#?[0-9]+\b|\bthe\s+lead\b",
    re.IGNORECASE,
)
PROSE_ONLY = re.compile(r"\b(?:lead|helper)s?\b(?!\s+to\b)", re.IGNORECASE)

BINARY_EXTENSIONS = {".png", ".jpg", ".jpeg", ".bin", ".mcap", ".gz", ".zst", ".pdf", ".ico"}
SKIPPED_PREFIXES = (
    "tests/data/",  # TUM RGB-D excerpts (third-party data, CC BY 4.0)
    "tests/fuzz/corpus/",  # fuzzer seed inputs
    "protocol/vectors/corpus/",  # fuzzer seed inputs derived from the golden vectors
)


def is_prose(path: str) -> bool:
    """Whether the prose-only rule applies to this repository-relative path."""
    return path == "README.md" or (path.startswith("docs/") and path.endswith(".md"))


def tracked_files(root: Path) -> list[str]:
    out = subprocess.run(
        ["git", "-C", str(root), "ls-files", "-z"], check=True, capture_output=True
    ).stdout
    return [p for p in out.decode("utf-8", "surrogateescape").split("\0") if p]


def is_skipped(path: str) -> bool:
    return path.startswith(SKIPPED_PREFIXES) or Path(path).suffix.lower() in BINARY_EXTENSIONS


def read_text(file: Path) -> str | None:
    """The file's text, or None for a binary file or one that cannot be read."""
    try:
        data = file.read_bytes()
    except OSError:
        return None
    if b"\0" in data[:8192]:
        return None
    return data.decode("utf-8", "replace")


def hits_in(path: str, text: str) -> list[tuple[int, str]]:
    """(line number, line) for each line of `text` that the rules flag."""
    prose = is_prose(path)
    found = []
    for number, line in enumerate(text.splitlines(), start=1):
        if EVERYWHERE.search(line) or (prose and PROSE_ONLY.search(line)):
            found.append((number, line.strip()))
    return found


def check(root: Path) -> list[str]:
    """Every flagged line in the repository at `root`, as `path:line: text`."""
    report = []
    for path in tracked_files(root):
        if is_skipped(path):
            continue
        text = read_text(root / path)
        if text is None:
            continue
        report.extend(f"{path}:{number}: {line}" for number, line in hits_in(path, text))
    return report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--root",
        type=Path,
        default=Path(__file__).resolve().parent.parent,
        help="repository to scan (default: the one holding this script)",
    )
    parser.add_argument(
        "--pending",
        action="append",
        default=[],
        metavar="DIR",
        help="report hits under DIR without failing on them",
    )
    args = parser.parse_args(argv)
    pending_prefixes = tuple(d.rstrip("/") + "/" for d in args.pending)
    hits = check(args.root)
    pending = [h for h in hits if h.startswith(pending_prefixes)] if pending_prefixes else []
    report = [h for h in hits if h not in pending]
    for line in report:
        print(line)
    if pending:
        print(f"check_history_words: pending (not failing) under {', '.join(args.pending)}:")
        for line in pending:
            print(f"  {line}")
    if report:
        print(
            f"check_history_words: {len(report)} line(s) narrate history (work periods, tracker "
            "entries, people); say what the system does and why instead",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
