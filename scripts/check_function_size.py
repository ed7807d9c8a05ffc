"""Fails when a production C++ function is longer than LIMIT_LINES lines.

Why 100 lines: the functions that had to be split (the receiver's per-stream serve loop,
quad-control's, slam-server's and slam-eval's `main`, `FlightController::update`,
`FlightRecorder::run`, at 138 to 226 lines) had each grown past 100 lines by taking one more
capability every time one was added, until they held several jobs that could not be tested apart.
Below 100, the longest functions left each still do one job (an MCAP file's close at 97 lines, the
keyframe decision at 93, one frame's encoding at 91, option tables at 80-85); a lower limit would
flag those, a higher one would have let the split ones grow on. clang-tidy's
readability-function-size would do the same but is not installed here; this stdlib scan needs
nothing else.

What counts: every tracked .c/.cc/.cpp/.h/.hpp file except tests (a `test`/`tests`/`fuzz`
folder, `*_test.*`, `test_*.*`, the top-level tests/ and hil/ rigs), generated code (a path with
`generated` in it, or a file saying "generated" / "do not edit" in its first lines) and third-party
code (`deps/`, `third_party/`, `vendor/`, `external/`). A function is counted from the first line
of its declaration to its closing brace; lambdas count in the function that holds them.

Functions still over the limit are listed, one a line with a one-line reason, in
scripts/function_size_allowlist.txt (`path:function  reason`); an entry whose function has come
under the limit is reported so that the list only shrinks.

    python3 scripts/check_function_size.py [--root DIR] [--limit N] [--allowlist FILE]

Exit status 0 when every function is within the limit or allowed, 1 otherwise.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

LIMIT_LINES = 100
SOURCE_SUFFIXES = (".c", ".cc", ".cpp", ".h", ".hpp")
TEST_DIRS = {"test", "tests", "fuzz", "testdata"}
THIRD_PARTY_DIRS = {"deps", "third_party", "vendor", "external", "node_modules"}
TOP_LEVEL_RIGS = {"tests", "hil"}  # test rigs and benches, not deployed code
GENERATED_MARK = re.compile(r"generated|do not edit", re.IGNORECASE)
SCOPE_HEAD = re.compile(
    r"^(?:\[\[[^\]]*\]\]\s*)*(?:(?:inline\s+)?namespace\b|extern\s*\"\"|"
    r"(?:typedef\s+)?(?:class|struct|union|enum)\b)"
)
TEMPLATE_PARAMS = re.compile(r"\btemplate\s*<")
NAME_BEFORE_PAREN = re.compile(
    r"((?:[A-Za-z_~][\w]*\s*::\s*)*(?:operator\s*[^\s(]+|[~A-Za-z_]\w*))\s*$"
)


@dataclass
class Function:
    path: str
    name: str
    first_line: int
    lines: int


def production_files(root: Path) -> list[str]:
    if (root / ".git").exists():
        out = subprocess.run(
            ["git", "-C", str(root), "ls-files", *(f"*{s}" for s in SOURCE_SUFFIXES)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
    else:
        out = []
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = [d for d in dirnames if not d.startswith((".", "build"))]
            for f in filenames:
                if f.endswith(SOURCE_SUFFIXES):
                    out.append(os.path.relpath(os.path.join(dirpath, f), root))
    return sorted(p for p in out if is_production(p) and not looks_generated(root / p))


def is_production(path: str) -> bool:
    parts = Path(path).parts
    name = parts[-1]
    if parts[0] in TOP_LEVEL_RIGS or "generated" in path.lower():
        return False
    if any(p in TEST_DIRS or p in THIRD_PARTY_DIRS for p in parts[:-1]):
        return False
    stem = name.rsplit(".", 1)[0]
    return not (stem.endswith("_test") or stem.startswith("test_") or stem.endswith("_tests"))


def looks_generated(path: Path) -> bool:
    try:
        with path.open(encoding="utf-8", errors="replace") as f:
            head = "".join(f.readline() for _ in range(5))
    except OSError:
        return False
    return bool(GENERATED_MARK.search(head))


def strip_code(text: str) -> str:
    """Comments, string and character literals and preprocessor lines blanked; newlines kept."""
    out: list[str] = []
    i, n = 0, len(text)
    at_line_start = True
    while i < n:
        c = text[i]
        if at_line_start and c in " \t":
            out.append(c)
            i += 1
            continue
        if at_line_start and c == "#":  # preprocessor line, with continuations
            while i < n and text[i] != "\n":
                if text[i] == "\\" and i + 1 < n and text[i + 1] == "\n":
                    out.append("\n")
                    i += 2
                    continue
                i += 1
            continue
        at_line_start = c == "\n"
        if text.startswith("//", i):
            while i < n and text[i] != "\n":
                i += 1
            continue
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            end = n if end < 0 else end + 2
            out.append("\n" * text.count("\n", i, end))
            i = end
            continue
        raw = re.match(r'R"([^(\s]{0,16})\(', text[i : i + 20])
        if raw and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            close = ")" + raw.group(1) + '"'
            end = text.find(close, i + raw.end())
            end = n if end < 0 else end + len(close)
            out.append('""' + "\n" * text.count("\n", i, end))
            i = end
            continue
        if c == '"' or (c == "'" and not is_digit_separator(text, i)):
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
            continue
        out.append(c)
        i += 1
    return "".join(out)


def is_digit_separator(text: str, i: int) -> bool:
    """True for the ' in 1'000'000: the token it stands in starts with a digit."""
    j = i
    while j > 0 and (text[j - 1].isalnum() or text[j - 1] in "_'."):
        j -= 1
    return j < i and text[j].isdigit()


def drop_template_params(head: str) -> str:
    while m := TEMPLATE_PARAMS.search(head):
        depth, j = 0, m.end() - 1
        while j < len(head):
            depth += {"<": 1, ">": -1}.get(head[j], 0)
            j += 1
            if depth == 0:
                break
        head = head[: m.start()] + head[j:]
    return head.strip()


def function_name(head: str) -> str | None:
    """The declared name when `head` (text before a `{`) declares a function body, else None."""
    head = drop_template_params(head)
    if not head or SCOPE_HEAD.match(head) or "(" not in head:
        return None
    if head.rstrip().endswith(("=", ",", "return")):
        return None
    depth, first_paren = 0, -1
    for k, ch in enumerate(head):
        if ch in "<":
            depth += 1
        elif ch == ">" and depth > 0:
            depth -= 1
        elif ch == "(" and depth == 0:
            first_paren = k
            break
    if first_paren < 0:
        return None
    m = NAME_BEFORE_PAREN.search(head[:first_paren])
    if m:
        return re.sub(r"\s+", "", m.group(1))
    return "lambda" if "]" in head[:first_paren] else None


def functions_in(path: str, text: str) -> list[Function]:
    code = strip_code(text)
    found: list[Function] = []
    head_start = 0
    i, n = 0, len(code)
    while i < n:
        c = code[i]
        if c in ";}":
            head_start = i + 1
        elif c == "{":
            head = code[head_start:i]
            if member_initialiser(head):  # `b_{x}` inside a constructor's initialiser list
                i = matching_brace(code, i) + 1
                continue
            name = function_name(" ".join(head.split()))
            if name is None:
                if SCOPE_HEAD.match(drop_template_params(" ".join(head.split()))):
                    head_start = i + 1  # namespace/class body: look inside
                else:
                    i = matching_brace(code, i)  # an initialiser or enum: skip it
                    head_start = i + 1
            else:
                end = matching_brace(code, i)
                offset = len(head) - len(head.lstrip())
                first = code.count("\n", 0, head_start + offset) + 1
                last = code.count("\n", 0, end) + 1
                found.append(Function(path, name, first, last - first + 1))
                i = end
                head_start = i + 1
        i += 1
    return found


def member_initialiser(head: str) -> bool:
    flat = " ".join(head.split())
    return bool(re.search(r"\)\s*(?:noexcept\s*)?:[^:].*[\w>]\s*$", flat)) and not flat.endswith(
        ")"
    )


def matching_brace(code: str, i: int) -> int:
    depth = 0
    for j in range(i, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


def read_allowlist(path: Path) -> dict[str, str]:
    allowed: dict[str, str] = {}
    if not path.exists():
        return allowed
    for line in path.read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        key, _, reason = line.partition(" ")
        allowed[key] = reason.strip()
    return allowed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--limit", type=int, default=LIMIT_LINES)
    ap.add_argument("--allowlist", type=Path, default=None)
    args = ap.parse_args(argv)
    root = args.root.resolve()
    allowlist = args.allowlist or root / "scripts" / "function_size_allowlist.txt"
    allowed = read_allowlist(allowlist)
    too_long: list[Function] = []
    seen_allowed: set[str] = set()
    files = production_files(root)
    for p in files:
        text = (root / p).read_text(encoding="utf-8", errors="replace")
        for f in functions_in(p, text):
            if f.lines <= args.limit:
                continue
            key = f"{f.path}:{f.name}"
            if key in allowed:
                seen_allowed.add(key)
            else:
                too_long.append(f)
    print(f"check_function_size: {len(files)} files, limit {args.limit} lines")
    for key in sorted(set(allowed) - seen_allowed):
        print(f"  allow-list entry no longer needed (remove it): {key}")
    for f in sorted(too_long, key=lambda f: -f.lines):
        print(f"  {f.path}:{f.first_line}: {f.name} is {f.lines} lines (limit {args.limit})")
    if too_long:
        print("check_function_size: split these into named steps (or, with a reason, allow-list)")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
