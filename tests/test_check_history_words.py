"""scripts/check_history_words.py on throw-away git repositories: a planted work-period line fails
the check and names its file and line; a file describing the system passes; code comments may say
"helper"; prose may not.

The flagged words are assembled at run time so that this file itself passes the check.
"""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CHECKER = REPO / "scripts" / "check_history_words.py"

WORK_PERIOD = "sess" + "ion 7"
TRACKER_ENTRY = "iss" + "ue #12"


def make_repo(root: Path, files: dict[str, str]) -> Path:
    subprocess.run(["git", "init", "-q", str(root)], check=True)
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    subprocess.run(["git", "-C", str(root), "add", "."], check=True)
    return root


def run_checker(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(CHECKER), "--root", str(root)],
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.parametrize(
    "name,line",
    [
        ("docs/slam.md", f"Measured in {WORK_PERIOD}: 0.4 m."),
        ("src/stage.cpp", f"// Raised in {TRACKER_ENTRY} after a flight."),
        ("tool.py", f"# {WORK_PERIOD.upper()} turned this on"),
        ("src/link.cpp", "// logs " + "sess" + "ion 00000000000000ab resumed"),
        ("docs/hil.md", "Flown by the " + "helper on an idle machine."),
        ("README.md", "A decision for the " + "lead."),
    ],
)
def test_planted_history_line_fails_and_is_named(tmp_path, name, line):
    # GIVEN a repository with one history line among descriptive ones
    root = make_repo(tmp_path / "repo", {name: f"What the stage does.\n{line}\nWhy.\n"})
    # WHEN the checker runs
    out = run_checker(root)
    # THEN it fails and prints path:line: text
    assert out.returncode == 1, out.stdout + out.stderr
    assert out.stdout.strip() == f"{name}:2: {line}"


def test_clean_tree_passes(tmp_path):
    # GIVEN descriptive text, the word session without a number, code that says "helper",
    # a map named by its hexadecimal identifier and the verb phrase "leads to" in prose
    root = make_repo(
        tmp_path / "repo",
        {
            "src/geometry.hpp": "// Small geometry helpers: angle wrapping.\n",
            "src/test.py": '"""Map 0x2a resumes from its checkpoint."""\n',
            "README.md": "Run `make test`.\n",
            "docs/slam.md": "A stream session keeps one key; a stall leads to relocalisation.\n"
            "`slam-server --max-sessions 4` holds four maps.\n",
        },
    )
    # WHEN the checker runs THEN it passes silently
    out = run_checker(root)
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout == ""


def test_third_party_data_and_binary_files_are_skipped(tmp_path):
    # GIVEN the words inside TUM data and a binary file
    root = make_repo(
        tmp_path / "repo",
        {"tests/data/fr1/groundtruth.txt": f"# {WORK_PERIOD}\n", "ok.md": "fine\n"},
    )
    (root / "blob.dat").write_bytes(b"\0\1" + WORK_PERIOD.encode())
    subprocess.run(["git", "-C", str(root), "add", "."], check=True)
    # WHEN the checker runs THEN neither is reported
    out = run_checker(root)
    assert out.returncode == 0, out.stdout + out.stderr


def test_hits_in_a_pending_folder_are_reported_without_failing(tmp_path):
    # GIVEN a history line in a folder being rewritten and a clean file elsewhere
    root = make_repo(
        tmp_path / "repo",
        {"engine/stage.cpp": f"// {WORK_PERIOD}\n", "docs/a.md": "fine\n"},
    )
    # WHEN the checker runs with that folder pending
    out = subprocess.run(
        [sys.executable, str(CHECKER), "--root", str(root), "--pending", "engine"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    # THEN it passes and still names the line
    assert out.returncode == 0, out.stdout + out.stderr
    assert "engine/stage.cpp:1:" in out.stdout
