"""Deployables (firmware/, onboard/, offboard/) may depend only on themselves and on the shared
contract folders; anything that crosses goes through protocol/ (wire formats) or lives in hil/ or
tests/ (the rig and cross-deployable end-to-end tests may use every part).

The scan covers C/C++ includes (resolved against the headers in the tree), CMake references to
another deployable's folder or targets, and Python imports of modules that exist only in another
deployable or in the rig. There are none left (KNOWN is empty): any crossing fails.
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

# (deployable file, what it reaches into) allowed to cross. Empty: code both sides need lives in
# protocol/, code that needs both sides in hil/ or tests/.
# Keep it empty: a crossing is fixed by moving code, not by listing it here.
KNOWN: set[tuple[str, str]] = set()


def _files(suffixes: tuple[str, ...], root: pathlib.Path = ROOT) -> list[pathlib.Path]:
    out = []
    for top in (*DEPLOYABLES, *SHARED, "hil", "tests"):
        base = root / top
        if not base.is_dir():
            continue
        for p in base.rglob("*"):
            rel = p.relative_to(root)
            if (
                p.is_file()
                and p.name.endswith(suffixes)
                and not (SKIP_PARTS & set(rel.parts))
                and not rel.parts[0].startswith("build")
            ):
                out.append(p)
    return out


def _top(path: pathlib.Path, root: pathlib.Path = ROOT) -> str:
    return path.relative_to(root).parts[0]


def _allowed(user_top: str, owner_tops: set[str]) -> bool:
    return user_top in owner_tops or bool(owner_tops & set(SHARED))


def cpp_crossings(root: pathlib.Path = ROOT) -> set[tuple[str, str]]:
    headers = [p for p in _files((".h", ".hpp"), root) if _top(p, root) != "tests"]
    include_re = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]', re.M)
    found = set()
    for src in _files((".c", ".cc", ".cpp", ".h", ".hpp"), root):
        top = _top(src, root)
        if top not in DEPLOYABLES:
            continue
        for inc in include_re.findall(src.read_text(errors="replace")):
            owners = [h for h in headers if h.as_posix().endswith("/" + inc)]
            tops = {_top(h, root) for h in owners}
            if owners and not _allowed(top, tops):
                first = sorted(owners)[0].relative_to(root).parts
                found.add((src.relative_to(root).as_posix(), "/".join(first[:2])))
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


def python_crossings(root: pathlib.Path = ROOT) -> set[tuple[str, str]]:
    pys = _files((".py",), root)
    owners: dict[str, set[str]] = {}
    for p in pys:
        name = p.parent.name if p.name == "__init__.py" else p.stem
        owners.setdefault(name, set()).add(_top(p, root))
    stdlib = set(sys.stdlib_module_names)
    found = set()
    for p in pys:
        top = _top(p, root)
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
                    found.add((p.relative_to(root).as_posix(), f"{sorted(tops)[0]}:{n}"))
    return found


def test_no_new_crossing_between_deployables():
    found = cpp_crossings() | cmake_crossings() | python_crossings()
    new = sorted(found - KNOWN)
    assert not new, (
        "a deployable reaches into another deployable or the rig; go through protocol/ or move the "
        "code to tests/ or hil/:\n" + "\n".join(f"  {f} -> {t}" for f, t in new)
    )


def test_the_scan_finds_a_crossing(tmp_path):
    # GIVEN a small tree where offboard/ imports the rig and firmware/ includes an onboard header,
    # next to allowed uses of protocol/ WHEN it is scanned THEN exactly the two crossings are found.
    files = {
        "hil/hilrig/__init__.py": "",
        "protocol/python/rgbd_protocol/__init__.py": "",
        "offboard/tool.py": "import hilrig\nimport rgbd_protocol\nimport json\n",
        "onboard/net/socket.h": "#pragma once\n",
        "protocol/control/include/rgbd_control/c.h": "#pragma once\n",
        "firmware/core/a.cpp": '#include "net/socket.h"\n#include "rgbd_control/c.h"\n',
    }
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    assert python_crossings(tmp_path) == {("offboard/tool.py", "hil:hilrig")}
    assert cpp_crossings(tmp_path) == {("firmware/core/a.cpp", "onboard/net")}
