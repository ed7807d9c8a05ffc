"""scripts/get_tum.py (`make data`, scripts/get-tum.sh) offline: a loopback HTTP server in this
process serves .tgz archives built from tests/data in the benchmark's layout, and a sequence table
pointing at it replaces the real one (same checks, other values).

GIVEN an archive WHEN its size and sha256 match THEN it is unpacked and the excerpts are cut with
the files of ../shared/data; WHEN the checksum is wrong, the download is truncated, the name is
unknown, the server is unreachable or the disk is full THEN the exit status and message say so and
nothing is left where the benchmarks read. With ../shared/data present, archives rebuilt from its
excerpts are cut back into identical folders.
"""

from __future__ import annotations

import errno
import hashlib
import io
import json
import shutil
import socket
import subprocess
import sys
import tarfile
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

import get_tum  # noqa: E402

TESTS_DATA = REPO / "tests" / "data"
SHARED = REPO.parent / "shared" / "data"
REAL_TABLE = REPO / "scripts" / "tum_sequences.json"


# ---- archives in the benchmark's layout ----------------------------------------------------------


def build_archive(
    src: Path, top: str, lists: dict[str, Path] | None = None, skip: tuple[str, ...] = ()
) -> bytes:
    """A .tgz holding `top/` with src's files; `lists` replaces rgb.txt/depth.txt (an excerpt's
    *_full_sequence.txt become the sequence's own lists, as in the benchmark's archive)."""
    lists = lists or {}
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz", compresslevel=1) as tar:
        tar.add(src / "rgb", arcname=f"{top}/rgb")
        tar.add(src / "depth", arcname=f"{top}/depth")
        for f in sorted(src.glob("*.txt")):
            if f.name in skip or f.name.endswith("_full_sequence.txt") or f.name == "associate.txt":
                continue
            tar.add(lists.get(f.name, f), arcname=f"{top}/{f.name}")
    return buf.getvalue()


def desk_archive(src: Path = TESTS_DATA / "fr1_desk_9frames") -> bytes:
    return build_archive(
        src,
        "rgbd_dataset_freiburg1_desk",
        {"rgb.txt": src / "rgb_full_sequence.txt", "depth.txt": src / "depth_full_sequence.txt"},
    )


class Server:
    """Loopback HTTP server in a thread. files: path -> bytes; truncate: paths whose body is cut in
    half while the full Content-Length is announced (a connection that breaks off)."""

    def __init__(self):
        self.files: dict[str, bytes] = {}
        self.truncate: set[str] = set()
        self.requests: list[str] = []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (the http.server API)
                outer.requests.append(self.path)
                body = outer.files.get(self.path)
                if body is None:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body[: len(body) // 2] if self.path in outer.truncate else body)

            def log_message(self, *args):
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def url(self, path: str) -> str:
        return f"http://127.0.0.1:{self.httpd.server_address[1]}{path}"

    def stop(self):
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(timeout=10)


@pytest.fixture
def server():
    s = Server()
    yield s
    s.stop()


def make_table(
    tmp: Path,
    server: Server,
    archives: dict[str, bytes],
    pin: bool = True,
    extra_excerpts: dict | None = None,
) -> Path:
    """The real table with each named sequence served by `server` and pinned to its archive."""
    table = json.loads(REAL_TABLE.read_text())
    for name, body in archives.items():
        seq = table["sequences"][name]
        path = f"/{seq['tum_name']}.tgz"
        server.files[path] = body
        seq["urls"] = [server.url(path)]
        seq["bytes"] = len(body) if pin else None
        seq["sha256"] = hashlib.sha256(body).hexdigest() if pin else None
    table["excerpts"].update(extra_excerpts or {})
    out = tmp / "table.json"
    out.write_text(json.dumps(table))
    return out


def run_script(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(REPO / "scripts" / "get-tum.sh"), "--quiet", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
    )


def assert_nothing_left(root: Path, excerpt: str, tum_name: str):
    assert not (root / "tum" / excerpt).exists()
    assert not (root / "tum-full" / tum_name).exists()
    assert not list(root.glob(".get-tum-tmp-*")), "temporary files left behind"


# ---- good archives -------------------------------------------------------------------------------


def test_good_archive_is_unpacked_and_the_excerpt_is_cut_as_in_shared_data(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    root = tmp_path / "data"
    r = run_script("fr1_desk", "--root", root, "--table", table)
    assert r.returncode == 0, r.stderr
    assert "matches the pinned" in r.stderr and "cut fr1_desk_9frames" in r.stderr
    src, out = TESTS_DATA / "fr1_desk_9frames", root / "tum" / "fr1_desk_9frames"
    for f in (
        "rgb.txt",
        "depth.txt",
        "groundtruth.txt",
        "rgb_full_sequence.txt",
        "depth_full_sequence.txt",
    ):
        assert (out / f).read_bytes() == (src / f).read_bytes(), f
    for sub in ("rgb", "depth"):
        names = sorted(p.name for p in (src / sub).iterdir())
        assert sorted(p.name for p in (out / sub).iterdir()) == names
        assert all((out / sub / n).read_bytes() == (src / sub / n).read_bytes() for n in names)
    # associate.py's pairs for all 9 frames; the shipped file holds the first two of them.
    pairs = (out / "associate.txt").read_text()
    assert len(pairs.splitlines()) == 9
    assert pairs.startswith((src / "associate.txt").read_text())
    stamp = json.loads(
        (root / "tum-full" / "rgbd_dataset_freiburg1_desk" / ".get-tum.json").read_text()
    )
    assert stamp["checked_against"] == "pinned"
    assert not list(root.glob(".get-tum-tmp-*"))


def test_excerpt_of_a_longer_sequence_takes_its_first_frames(tmp_path, server):
    src = TESTS_DATA / "fr1_xyz_first30"
    table = make_table(
        tmp_path,
        server,
        {"fr1_xyz": build_archive(src, "rgbd_dataset_freiburg1_xyz")},
        extra_excerpts={
            "fr1_xyz_first10": {
                "sequence": "fr1_xyz",
                "frames": 10,
                "copies": ["groundtruth.txt", "accelerometer.txt"],
                "full_lists": True,
                "associate": None,
            }
        },
    )
    root = tmp_path / "data"
    r = run_script("fr1_xyz_first10", "--root", root, "--table", table)
    # The 300-frame excerpt cannot be cut from 30 frames: said, and not left half-made.
    assert r.returncode == 1 and "30 colour and" in r.stderr and "300 needed" in r.stderr
    assert not (root / "tum" / "fr1_xyz_first300").exists()
    table_obj = json.loads(table.read_text())
    del table_obj["excerpts"]["fr1_xyz_first300"]
    table.write_text(json.dumps(table_obj))
    r = run_script("fr1_xyz_first10", "--root", root, "--table", table)
    assert r.returncode == 0, r.stderr
    assert "already holds the verified archive" in r.stderr  # no second download
    out = root / "tum" / "fr1_xyz_first10"
    rows = [ln for ln in (out / "rgb.txt").read_text().splitlines() if not ln.startswith("#")]
    src_rows = [ln for ln in (src / "rgb.txt").read_text().splitlines() if not ln.startswith("#")]
    assert rows == src_rows[:10]
    assert len(list((out / "rgb").iterdir())) == 10 and len(list((out / "depth").iterdir())) == 10
    assert (out / "accelerometer.txt").read_bytes() == (src / "accelerometer.txt").read_bytes()
    assert (out / "rgb_full_sequence.txt").read_bytes() == (src / "rgb.txt").read_bytes()


# ---- refused downloads ---------------------------------------------------------------------------


def test_wrong_checksum_is_refused_and_nothing_is_left(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    t = json.loads(table.read_text())
    t["sequences"]["fr1_desk"]["sha256"] = "0" * 64
    table.write_text(json.dumps(t))
    root = tmp_path / "data"
    r = run_script("fr1_desk", "--root", root, "--table", table)
    assert r.returncode == 1
    assert "wrong checksum" in r.stderr and "0" * 64 in r.stderr
    assert_nothing_left(root, "fr1_desk_9frames", "rgbd_dataset_freiburg1_desk")


def test_truncated_download_is_refused(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    server.truncate.add("/rgbd_dataset_freiburg1_desk.tgz")
    root = tmp_path / "data"
    r = run_script("fr1_desk", "--root", root, "--table", table)
    assert r.returncode == 1 and "truncated" in r.stderr
    assert_nothing_left(root, "fr1_desk_9frames", "rgbd_dataset_freiburg1_desk")


def test_truncated_archive_on_the_server_is_refused_before_download(tmp_path, server):
    body = desk_archive()
    table = make_table(tmp_path, server, {"fr1_desk": body})
    server.files["/rgbd_dataset_freiburg1_desk.tgz"] = body[: len(body) - 1000]
    root = tmp_path / "data"
    r = run_script("fr1_desk", "--root", root, "--table", table)
    assert r.returncode == 1 and f"the archive must have {len(body)}" in r.stderr
    assert_nothing_left(root, "fr1_desk_9frames", "rgbd_dataset_freiburg1_desk")


def test_failed_redownload_keeps_the_previous_good_data(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    root = tmp_path / "data"
    assert run_script("fr1_desk", "--root", root, "--table", table).returncode == 0
    before = (root / "tum" / "fr1_desk_9frames" / "rgb.txt").read_bytes()
    server.truncate.add("/rgbd_dataset_freiburg1_desk.tgz")
    r = run_script("fr1_desk", "--force", "--root", root, "--table", table)
    assert r.returncode == 1 and "truncated" in r.stderr
    assert (root / "tum" / "fr1_desk_9frames" / "rgb.txt").read_bytes() == before
    assert (root / "tum-full" / "rgbd_dataset_freiburg1_desk" / "rgb.txt").is_file()
    assert not list(root.glob(".get-tum-tmp-*"))


# ---- bad input -----------------------------------------------------------------------------------


def test_unknown_sequence_name_is_a_usage_error(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    root = tmp_path / "data"
    r = run_script("fr1_desk", "fr7_nowhere", "--root", root, "--table", table)
    assert r.returncode == 2
    assert "unknown sequence 'fr7_nowhere'" in r.stderr and "fr1_desk" in r.stderr
    assert not root.exists() and server.requests == []


def test_no_network_connection_refused(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    with socket.socket() as s:  # a loopback port that nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t = json.loads(table.read_text())
    t["sequences"]["fr1_desk"]["urls"] = [
        f"http://127.0.0.1:{port}/a.tgz",
        f"http://127.0.0.1:{port}/b.tgz",
    ]
    table.write_text(json.dumps(t))
    root = tmp_path / "data"
    r = run_script("fr1_desk", "--root", root, "--table", table)
    assert r.returncode == 1
    assert "could not download the archive from any of its 2 addresses" in r.stderr
    assert "connection refused" in r.stderr
    assert_nothing_left(root, "fr1_desk_9frames", "rgbd_dataset_freiburg1_desk")
    assert not (root / "tum").exists()  # no empty DATA folder for the benches to run on


def test_full_disk_before_download_is_refused(tmp_path, server, monkeypatch, capsys):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    monkeypatch.setattr(get_tum, "free_bytes", lambda path: 10 << 20)
    root = tmp_path / "data"
    assert get_tum.main(["fr1_desk", "--quiet", "--root", str(root), "--table", str(table)]) == 1
    assert "not enough free disk space" in capsys.readouterr().err
    assert_nothing_left(root, "fr1_desk_9frames", "rgbd_dataset_freiburg1_desk")


def test_disk_filling_up_while_unpacking(tmp_path, server, monkeypatch, capsys):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})

    def no_space(self, path, *args, **kwargs):
        (Path(path) / "rgbd_dataset_freiburg1_desk").mkdir()  # a partial unpack, then ENOSPC
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(tarfile.TarFile, "extractall", no_space)
    root = tmp_path / "data"
    assert get_tum.main(["fr1_desk", "--quiet", "--root", str(root), "--table", str(table)]) == 1
    assert "the disk is full" in capsys.readouterr().err
    assert_nothing_left(root, "fr1_desk_9frames", "rgbd_dataset_freiburg1_desk")


# ---- sequences without a published checksum ------------------------------------------------------


def test_unpinned_sequence_needs_trust_on_first_use_then_is_checked(tmp_path, server):
    body = desk_archive()
    table = make_table(tmp_path, server, {"fr1_desk": body}, pin=False)
    root = tmp_path / "data"
    # Named after a pinned sequence, it still stops the run before any download starts.
    r = run_script("fr1_xyz", "fr1_desk", "--root", root, "--table", table)
    assert r.returncode == 1 and "fr1_desk: no published checksum" in r.stderr
    assert "--trust-on-first-use" in r.stderr and "downloading" not in r.stderr
    assert server.requests == []
    r = run_script("fr1_desk", "--trust-on-first-use", "--root", root, "--table", table)
    assert r.returncode == 0, r.stderr
    assert "trust on first use" in r.stderr
    lock = json.loads((root / "tum-lock.json").read_text())
    assert lock["fr1_desk"]["sha256"] == hashlib.sha256(body).hexdigest()
    assert lock["fr1_desk"]["bytes"] == len(body)
    # The recorded values now guard later downloads: a different archive is refused. One byte in
    # the middle is flipped: the last byte of a gzip file is the top byte of the unpacked size,
    # already 0 for an archive this small, so overwriting it with 0 changed nothing but the
    # header's timestamp, and only when the two archives were built in different seconds.
    other = bytearray(desk_archive())
    other[len(other) // 2] ^= 0xFF
    server.files["/rgbd_dataset_freiburg1_desk.tgz"] = bytes(other)
    r = run_script("fr1_desk", "--force", "--root", root, "--table", table)
    assert r.returncode == 1 and "wrong checksum" in r.stderr and "lock file" in r.stderr


# ---- pieces --------------------------------------------------------------------------------------


def test_associate_is_tum_associate_py_greedy_pairing():
    def rows(*stamps):
        return [(s, f"{s:.6f}", [f"x/{s}.png"]) for s in stamps]

    # 1.000 pairs with 1.005 (closest), so 1.010 takes 1.012, and 1.100 has nothing within 20 ms.
    pairs = get_tum.associate(rows(1.000, 1.010, 1.100), rows(1.005, 1.012, 1.300))
    assert [(a[0], b[0]) for a, b in pairs] == [(1.000, 1.005), (1.010, 1.012)]


def test_make_data_target_runs_the_script(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    root = tmp_path / "data"
    r = subprocess.run(
        [
            "make",
            "-s",
            "--no-print-directory",
            "data",
            "SEQ=fr1_desk",
            f"GET_TUM_ARGS=--quiet --root {root} --table {table}",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert (root / "tum" / "fr1_desk_9frames" / "rgb.txt").is_file()
    r = subprocess.run(
        [
            "make",
            "-s",
            "--no-print-directory",
            "data",
            "SEQ=fr1_none",
            f"GET_TUM_ARGS=--quiet --root {root} --table {table}",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode != 0 and "unknown sequence 'fr1_none'" in r.stderr


# ---- the shared excerpts, rebuilt --------------------------------------------------------------


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} is absent")
def test_archives_rebuilt_from_shared_data_give_the_same_folders(tmp_path, server):
    """Each shared excerpt packed as its sequence's archive (its *_full_sequence lists as the
    sequence's lists) is cut back into the same files; only associate.txt of fr1_desk_9frames
    differs: it lists all 9 pairs where the shared copy has the first two."""
    archives = {
        "fr1_desk": desk_archive(SHARED / "fr1_desk_9frames"),
        "fr1_360": build_archive(
            SHARED / "fr1_360_first60",
            "rgbd_dataset_freiburg1_360",
            {
                "rgb.txt": SHARED / "fr1_360_first60" / "rgb_full_sequence.txt",
                "depth.txt": SHARED / "fr1_360_first60" / "depth_full_sequence.txt",
            },
        ),
        "fr2_desk": build_archive(SHARED / "fr2_desk_first50", "rgbd_dataset_freiburg2_desk"),
    }
    table = make_table(tmp_path, server, archives)
    root = tmp_path / "data"
    r = run_script("fr1_desk", "fr1_360", "fr2_desk", "--root", root, "--table", table)
    assert r.returncode == 0, r.stderr
    for name in ("fr1_desk_9frames", "fr1_360_first60", "fr2_desk_first50"):
        ours, theirs = root / "tum" / name, SHARED / name
        files = sorted(str(p.relative_to(theirs)) for p in theirs.rglob("*") if p.is_file())
        assert sorted(str(p.relative_to(ours)) for p in ours.rglob("*") if p.is_file()) == files
        for f in files:
            if (name, f) == ("fr1_desk_9frames", "associate.txt"):
                assert (ours / f).read_text().startswith((theirs / f).read_text())
                continue
            assert (ours / f).read_bytes() == (theirs / f).read_bytes(), f"{name}/{f}"
    shutil.rmtree(root)


@pytest.mark.parametrize(
    "shared_present, expected", [(True, "../shared/data"), (False, "data/tum")]
)
def test_benches_read_data_tum_when_shared_data_is_absent(tmp_path, shared_present, expected):
    repo = tmp_path / "main"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy(REPO / "scripts" / "data-dir.sh", repo / "scripts")
    if shared_present:
        (tmp_path / "shared" / "data").mkdir(parents=True)
    r = subprocess.run(
        ["bash", str(repo / "scripts" / "data-dir.sh")], capture_output=True, text=True, timeout=30
    )
    assert r.returncode == 0 and r.stdout.strip() == expected


def test_malformed_table_and_lock_file_are_refused_with_their_path(tmp_path, server):
    table = make_table(tmp_path, server, {"fr1_desk": desk_archive()})
    t = json.loads(table.read_text())
    t["sequences"]["fr1_desk"]["sha256"] = "not-a-checksum"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(t))
    root = tmp_path / "data"
    r = run_script("fr1_desk", "--root", root, "--table", bad)
    assert r.returncode == 2 and "sequence fr1_desk: bytes must be a count" in r.stderr
    root.mkdir()
    (root / "tum-lock.json").write_text('{"fr1_360": {"bytes": 5}}')
    r = run_script("fr1_360", "--root", root, "--table", table)
    assert r.returncode == 1 and "entry 'fr1_360' is not a size and a sha256" in r.stderr
    assert server.requests == []
