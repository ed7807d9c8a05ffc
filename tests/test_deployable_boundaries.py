"""Deployables (firmware/, onboard/, offboard/) may depend only on themselves and on the shared
contract folders; anything that crosses goes through protocol/ (wire formats) or lives in hil/ or
tests/ (the rig and cross-deployable end-to-end tests may use every part).

The scan covers C/C++ includes (resolved against the headers in the tree), CMake references to
another deployable's folder or targets, and Python imports of modules that exist only in another
deployable or in the rig. Crossings that existed when this check was written are listed in KNOWN
(each one is a step of issue #14's "deployables depend only on shared contracts"); a new crossing
fails, and so does a listed one that has gone (delete it from the list: the list only shrinks).
"""
from __future__ import annotations

import ast
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEPLOYABLES = ("firmware", "onboard", "offboard")
# Folders every deployable may use: the wire contracts and the build helpers.
SHARED = ("protocol", "cmake")
SKIP_PARTS = {".git", ".venv", "node_modules", ".pio", "test-artifacts", "__pycache__", "data"}

# (deployable file, what it reaches into) present when the check was introduced.
KNOWN = {
    ("firmware/tests/test_simavr.py", "hil:arduino"),
    ("offboard/dashboard/tests/conftest.py", "hil:wifi_bridge"),
    ("offboard/quadcontrol/tools/measure_links.py", "hil:wifi_bridge"),
    ("offboard/slamlink/tests/test_slam_link_resume_e2e.py", "hil:hilrig"),
}


def _files(suffixes: tuple[str, ...]) -> list[pathlib.Path]:
    out = []
    for top in (*DEPLOYABLES, *SHARED, "hil", "tests"):
        base = ROOT / top
        if not base.is_dir():
            continue
        for p in base.rglob("*"):
            rel = p.relative_to(ROOT)
            if p.is_file() and p.name.endswith(suffixes) and not (SKIP_PARTS & set(rel.parts)) \
                    and not rel.parts[0].startswith("build"):
                out.append(p)
    return out


def _top(path: pathlib.Path) -> str:
    return path.relative_to(ROOT).parts[0]


def _allowed(user_top: str, owner_tops: set[str]) -> bool:
    return user_top in owner_tops or bool(owner_tops & set(SHARED))


def cpp_crossings() -> set[tuple[str, str]]:
    headers = [p for p in _files((".h", ".hpp")) if _top(p) != "tests"]
    include_re = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]', re.M)
    found = set()
    for src in _files((".c", ".cc", ".cpp", ".h", ".hpp")):
        top = _top(src)
        if top not in DEPLOYABLES:
            continue
        for inc in include_re.findall(src.read_text(errors="replace")):
            owners = [h for h in headers if h.as_posix().endswith("/" + inc)]
            tops = {_top(h) for h in owners}
            if owners and not _allowed(top, tops):
                first = sorted(owners)[0].relative_to(ROOT).parts
                found.add((src.relative_to(ROOT).as_posix(), "/".join(first[:2])))
    return found


def cmake_crossings() -> set[tuple[str, str]]:
    lists = _files(("CMakeLists.txt",))
    owner_of_target = {}
    define_re = re.compile(r"add_(?:library|executable)\s*\(\s*([A-Za-z0-9_.+-]+)")
    for cm in lists:
        for name in define_re.findall(cm.read_text()):
            owner_of_target.setdefault(name, _top(cm))
    path_re = re.compile(r"\$\{(?:PROJECT|CMAKE)_SOURCE_DIR\}/([A-Za-z0-9_-]+)/([A-Za-z0-9_-]+)")
    link_re = re.compile(r"target_link_libraries\s*\(([^)]*)\)", re.S)
    found = set()
    for cm in lists:
        top = _top(cm)
        if top not in DEPLOYABLES:
            continue
        text = re.sub(r"#.*", "", cm.read_text())
        rel = cm.relative_to(ROOT).as_posix()
        for a, b in path_re.findall(text):
            if a not in (top, *SHARED) and a in (*DEPLOYABLES, "hil"):
                found.add((rel, f"{a}/{b}"))
        for args in link_re.findall(text):
            for tok in args.split()[1:]:
                owner = owner_of_target.get(tok)
                if owner and not _allowed(top, {owner}):
                    found.add((rel, f"{owner}:{tok}"))
    return found


def python_crossings() -> set[tuple[str, str]]:
    pys = _files((".py",))
    owners: dict[str, set[str]] = {}
    for p in pys:
        name = p.parent.name if p.name == "__init__.py" else p.stem
        owners.setdefault(name, set()).add(_top(p))
    stdlib = set(sys.stdlib_module_names)
    found = set()
    for p in pys:
        top = _top(p)
        if top not in DEPLOYABLES:
            continue
        try:
            tree = ast.parse(p.read_text(errors="replace"))
        except SyntaxError:
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name.split(".")[0] for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module.split(".")[0]]
            else:
                continue
            for n in names:
                tops = owners.get(n)
                if tops and n not in stdlib and n != "conftest" and not _allowed(top, tops):
                    found.add((p.relative_to(ROOT).as_posix(), f"{sorted(tops)[0]}:{n}"))
    return found


def test_no_new_crossing_between_deployables():
    found = cpp_crossings() | cmake_crossings() | python_crossings()
    new = sorted(found - KNOWN)
    assert not new, (
        "a deployable reaches into another deployable or the rig; go through protocol/ or move the "
        "code to tests/ or hil/:\n" + "\n".join(f"  {f} -> {t}" for f, t in new))


def test_known_crossings_are_still_there():
    gone = sorted(KNOWN - (cpp_crossings() | cmake_crossings() | python_crossings()))
    assert not gone, "fixed crossings, delete them from KNOWN:\n" + "\n".join(
        f"  {f} -> {t}" for f, t in gone)
