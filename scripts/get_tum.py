#!/usr/bin/env python3
"""Download TUM RGB-D sequences, verify them, and cut the excerpts the benchmarks read.

`make data` and `scripts/get-tum.sh` run this. For each named sequence it downloads the archive
from the benchmark's site, checks its size and sha256 against the table in
scripts/tum_sequences.json (or the lock file, for a sequence whose checksum was recorded on first
use), unpacks it under ROOT/tum-full/, and cuts the excerpts that `make bench` and `make study`
read (fr1_xyz_first300, ...) into ROOT/tum/, with the same files as ../shared/data (docs/data.md).

Every step writes into a temporary folder beside its target (ROOT/.get-tum-tmp-*, the same file
system) and renames it into place only when the step has succeeded, so a failure (a wrong
checksum, a truncated download, no network, a full disk, Ctrl-C) leaves nothing half-written where
the benchmarks read. Standard library only, so it runs with the system python3 before `make deps`.

Exit status: 0 done; 1 a download, check or unpack failed; 2 bad usage (an unknown name).
"""

from __future__ import annotations

import argparse
import errno
import hashlib
import http.client
import json
import os
import shutil
import socket
import sys
import tarfile
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path, PurePosixPath

REPO = Path(__file__).resolve().parents[1]
DEFAULT_TABLE = REPO / "scripts" / "tum_sequences.json"
DEFAULT_ROOT = REPO / "data"
EXCERPTS_DIR = "tum"  # ROOT/tum: the DATA folder the benchmarks read when ../shared/data is absent
FULL_DIR = "tum-full"  # ROOT/tum-full: whole sequences, outside DATA so the benches skip them
LOCK_FILE = "tum-lock.json"  # checksums recorded with --trust-on-first-use
TMP_PREFIX = ".get-tum-tmp-"
STAMP_FILE = ".get-tum.json"  # provenance of an unpacked sequence (not read by the benches)

CHUNK_BYTES = 1 << 20  # read/hash granularity; 1 MiB keeps Python overhead negligible
# Free space kept spare beyond what a step writes: the file system's own metadata and the other
# users of the disk (logs, builds) must not be starved by a download.
DISK_MARGIN_BYTES = 256 << 20
CONNECT_TIMEOUT_S = 30  # per socket operation; a stalled server fails instead of hanging
PROGRESS_INTERVAL_S = 2.0  # at most one progress line per interval when stderr is not a terminal
TTY_REFRESH_S = 0.2  # a terminal's progress line is redrawn in place, at most 5 times a second
# The benchmark's association rule (TUM associate.py): pairs closer than 20 ms.
ASSOCIATE_MAX_DT_S = 0.02
# Frames beyond an excerpt's length searched for its first colour/depth pair: the depth stream of
# fr1_desk starts 17 colour frames (0.6 s) late; 256 (8.5 s at 30 Hz) leaves ample room.
HEAD_EXTRA_FRAMES = 256

EXIT_FAILED = 1
EXIT_USAGE = 2


class GetTumError(Exception):
    """A failure with a message for the user; nothing is left half-written when it is raised."""


class UsageError(GetTumError):
    """Bad command-line input (exit status 2)."""


@dataclass
class Expected:
    """What a download must match: size and sha256 (either may be unknown) and their origin."""

    size_bytes: int | None
    sha256: str | None
    origin: str  # "pinned", "lock file" or "trust on first use"


def log(msg: str) -> None:
    print(f"get-tum: {msg}", file=sys.stderr, flush=True)


# ---- table and lock file -------------------------------------------------------------------------


def load_table(path: Path) -> dict:
    try:
        table = json.loads(path.read_text())
    except OSError as e:
        raise UsageError(f"cannot read the sequence table {path}: {e.strerror}") from e
    except json.JSONDecodeError as e:
        raise UsageError(f"{path}: not valid JSON ({e})") from e
    for key in ("sequences", "excerpts"):
        if not isinstance(table.get(key), dict):
            raise UsageError(f"{path}: no '{key}' object")
    for name, seq in table["sequences"].items():
        for field in ("tum_name", "urls", "bytes", "sha256"):
            if field not in seq:
                raise UsageError(f"{path}: sequence {name} has no '{field}'")
        if not valid_size_and_sha(seq["bytes"], seq["sha256"], allow_none=True):
            raise UsageError(
                f"{path}: sequence {name}: bytes must be a count and sha256 64 hex "
                "digits (or both may be null)"
            )
    for name, ex in table["excerpts"].items():
        if ex.get("sequence") not in table["sequences"]:
            raise UsageError(f"{path}: excerpt {name} names an unknown sequence")
    return table


def valid_size_and_sha(size, sha, allow_none: bool) -> bool:
    if allow_none and sha is None:
        return size is None or (isinstance(size, int) and size > 0)
    return (
        isinstance(size, int)
        and size > 0
        and isinstance(sha, str)
        and len(sha) == 64
        and all(c in "0123456789abcdefABCDEF" for c in sha)
    )


def read_lock(root: Path) -> dict:
    path = root / LOCK_FILE
    if not path.exists():
        return {}
    try:
        lock = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise GetTumError(f"cannot read the lock file {path}: {e}") from e
    for name, entry in lock.items() if isinstance(lock, dict) else [("", None)]:
        if not isinstance(entry, dict) or not valid_size_and_sha(
            entry.get("bytes"), entry.get("sha256"), allow_none=False
        ):
            raise GetTumError(
                f"{path}: entry '{name}' is not a size and a sha256; fix or delete it"
            )
    return lock


def write_json_atomic(path: Path, value: dict) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=TMP_PREFIX, suffix=".json")
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(value, f, indent=2, sort_keys=True)
            f.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def expected_for(name: str, seq: dict, lock: dict, trust_first_use: bool) -> Expected:
    """The pinned size/sha256, else the lock file's, else (only if allowed) none yet."""
    if seq["sha256"]:
        return Expected(seq["bytes"], seq["sha256"].lower(), "pinned")
    if name in lock:
        entry = lock[name]
        return Expected(entry["bytes"], entry["sha256"].lower(), "lock file")
    if not trust_first_use:
        raise GetTumError(
            f"{name}: no published checksum is pinned for this archive, so its download cannot be "
            "verified. Pass --trust-on-first-use to accept this download and record its size and "
            f"sha256 in {LOCK_FILE} (later downloads are checked against them); see docs/data.md"
        )
    return Expected(seq["bytes"], None, "trust on first use")


# ---- download ------------------------------------------------------------------------------------


def free_bytes(path: Path) -> int:
    return shutil.disk_usage(path).free


def require_space(where: Path, needed_bytes: int, what: str) -> None:
    free = free_bytes(where)
    if free < needed_bytes + DISK_MARGIN_BYTES:
        raise GetTumError(
            f"not enough free disk space in {where} for {what}: {needed_bytes / 1e6:.0f} MB needed "
            f"plus a {DISK_MARGIN_BYTES >> 20} MiB margin, {free / 1e6:.0f} MB free"
        )


class Progress:
    """Download progress on stderr: one updating line on a terminal, else a line every 2 s."""

    def __init__(self, label: str, total: int | None, quiet: bool):
        self.label, self.total, self.quiet = label, total, quiet
        self.tty = sys.stderr.isatty()
        self.last = 0.0

    def update(self, done: int, final: bool = False) -> None:
        if self.quiet:
            return
        now = time.monotonic()
        if not final and now - self.last < (TTY_REFRESH_S if self.tty else PROGRESS_INTERVAL_S):
            return
        self.last = now
        pct = f" {100.0 * done / self.total:5.1f}%" if self.total else ""
        total = f" of {self.total / 1e6:.1f}" if self.total else ""
        line = f"get-tum: {self.label}: {done / 1e6:.1f}{total} MB{pct}"
        if self.tty:
            sys.stderr.write("\r" + line + ("\n" if final else ""))
        else:
            sys.stderr.write(line + "\n")
        sys.stderr.flush()


def describe_url_error(url: str, e: Exception) -> str:
    reason = getattr(e, "reason", e)
    if isinstance(e, urllib.error.HTTPError):
        return f"{url}: the server answered HTTP {e.code} {e.reason}"
    if isinstance(reason, ConnectionRefusedError):
        return f"{url}: connection refused"
    if isinstance(reason, socket.gaierror):
        return f"{url}: the host name cannot be resolved (no network, or no DNS)"
    if isinstance(reason, OSError) and reason.errno in (errno.ENETUNREACH, errno.EHOSTUNREACH):
        return f"{url}: network unreachable (no network?)"
    return f"{url}: {reason}"


def fetch(url: str, dest: Path, exp: Expected, label: str, quiet: bool) -> tuple[int, str]:
    """Stream url into dest, hashing as it goes; returns (bytes written, sha256 hex)."""
    req = urllib.request.Request(url, headers={"User-Agent": "get-tum (rgbd-quad benchmarks)"})
    with urllib.request.urlopen(req, timeout=CONNECT_TIMEOUT_S) as resp:
        announced = resp.headers.get("Content-Length")
        announced = int(announced) if announced and announced.isdigit() else None
        if exp.size_bytes is not None and announced is not None and announced != exp.size_bytes:
            raise GetTumError(
                f"{label}: the server announces {announced} bytes, the archive must have "
                f"{exp.size_bytes} ({exp.origin}); refused without downloading"
            )
        require_space(dest.parent, announced or exp.size_bytes or 0, f"the {label} archive")
        digest, done = hashlib.sha256(), 0
        progress = Progress(label, exp.size_bytes or announced, quiet)
        with open(dest, "wb") as out:
            while True:
                try:
                    chunk = resp.read(CHUNK_BYTES)
                except (OSError, http.client.HTTPException) as e:  # reset, timeout, IncompleteRead
                    raise GetTumError(
                        f"{label}: the download broke off after {done} bytes ({e})"
                    ) from e
                if not chunk:
                    break
                out.write(chunk)
                digest.update(chunk)
                done += len(chunk)
                progress.update(done)
        progress.update(done, final=True)
        if announced is not None and done != announced:
            raise GetTumError(
                f"{label}: truncated download: {done} of the announced {announced} bytes arrived"
            )
    return done, digest.hexdigest()


def download(seq: dict, dest: Path, exp: Expected, label: str, quiet: bool) -> tuple[str, str]:
    """Tries each URL in turn; returns (url, sha256) of a download that matches `exp`."""
    failures = []
    for url in seq["urls"]:
        log(f"{label}: downloading {url}")
        try:
            size, sha = fetch(url, dest, exp, label, quiet)
        except (urllib.error.URLError, TimeoutError, ConnectionError) as e:
            failures.append(describe_url_error(url, e))
            log(f"{label}: {failures[-1]}")
            continue
        if exp.size_bytes is not None and size != exp.size_bytes:
            raise GetTumError(
                f"{label}: wrong size: {size} bytes downloaded, {exp.size_bytes} expected "
                f"({exp.origin}); the download is truncated or not the benchmark's archive"
            )
        if exp.sha256 is not None and sha != exp.sha256:
            raise GetTumError(
                f"{label}: wrong checksum: sha256 {sha}, expected {exp.sha256} ({exp.origin}); "
                "the download is corrupt or not the benchmark's archive"
            )
        return url, sha
    raise GetTumError(
        f"{label}: could not download the archive from any of its {len(failures)} addresses "
        f"(no network, or the site is down): " + "; ".join(failures)
    )


# ---- unpack --------------------------------------------------------------------------------------


def check_members(archive: Path, top: str) -> int:
    """Validates every member (one top folder `top`, plain files and folders, no path escapes);
    returns the unpacked size in bytes. Reading the whole index also checks the gzip stream."""
    total = 0
    try:
        with tarfile.open(archive, "r:gz") as tar:
            for m in tar:
                parts = PurePosixPath(m.name).parts
                if not parts or parts[0] != top or ".." in parts or m.name.startswith("/"):
                    raise GetTumError(f"archive member '{m.name}' is outside the folder {top}/")
                if not (m.isfile() or m.isdir()):
                    raise GetTumError(f"archive member '{m.name}' is not a plain file or folder")
                total += m.size
    except (tarfile.TarError, EOFError, OSError) as e:
        raise GetTumError(f"the archive cannot be read ({e}): corrupt or truncated") from e
    return total


def unpack(archive: Path, into: Path, top: str) -> Path:
    """Unpacks into `into` after checking members and free space; returns the sequence folder."""
    size = check_members(archive, top)
    require_space(into, size, f"unpacking {archive.name} ({size / 1e6:.0f} MB)")
    try:
        with tarfile.open(archive, "r:gz") as tar:
            # check_members already refused links and paths leaving the folder; the "data" filter
            # (Python >= 3.11.4; Debian 12 ships 3.11.2) also drops set-uid bits and owners.
            extra = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}
            tar.extractall(into, **extra)
    except (tarfile.TarError, EOFError) as e:
        raise GetTumError(f"unpacking {archive.name} failed: {e}") from e
    folder = into / top
    missing = [
        f
        for f in ("rgb.txt", "depth.txt", "groundtruth.txt", "rgb", "depth")
        if not (folder / f).exists()
    ]
    if missing:
        raise GetTumError(f"{archive.name} is not a TUM RGB-D sequence: no {', '.join(missing)}")
    return folder


def replace_dir(new: Path, target: Path) -> None:
    """Moves `new` to `target`; an existing target is moved aside first and removed after, so the
    target path names the old complete folder, nothing (between two renames), or the new one."""
    target.parent.mkdir(parents=True, exist_ok=True)
    old = None
    if target.exists():
        old = new.parent / (target.name + ".old")
        os.rename(target, old)
    os.rename(new, target)
    if old is not None:
        shutil.rmtree(old)


# ---- excerpts ------------------------------------------------------------------------------------


def read_list(path: Path) -> tuple[list[str], list[tuple[float, str, list[str]]]]:
    """A TUM list file: its '#' header lines and its rows as (stamp, stamp text, other fields)."""
    header, rows = [], []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if line.startswith("#"):
            header.append(line)
            continue
        fields = line.replace(",", " ").replace("\t", " ").split()
        if not fields:
            continue
        try:
            rows.append((float(fields[0]), fields[0], fields[1:]))
        except ValueError as e:
            raise GetTumError(f"{path}:{n}: '{fields[0]}' is not a timestamp") from e
    return header, rows


def associate(first: list, second: list, max_dt_s: float = ASSOCIATE_MAX_DT_S) -> list:
    """TUM associate.py: greedy unique pairs by increasing |dt| below max_dt_s, sorted by the first
    stamp. Returns (first row, second row) pairs."""
    cands = sorted(
        (abs(a[0] - b[0]), i, j)
        for i, a in enumerate(first)
        for j, b in enumerate(second)
        if abs(a[0] - b[0]) < max_dt_s
    )
    used_a, used_b, pairs = set(), set(), []
    for _, i, j in cands:
        if i in used_a or j in used_b:
            continue
        used_a.add(i)
        used_b.add(j)
        pairs.append((i, j))
    pairs.sort()
    return [(first[i], second[j]) for i, j in pairs]


def cut_rows(full: Path, excerpt: dict, name: str) -> tuple[list, list, list, list]:
    """The excerpt's rgb and depth rows: `frames` rows of each, from the first colour frame that
    has a depth frame within 20 ms and that depth frame (the rule that gives ../shared/data)."""
    rgb_header, rgb = read_list(full / "rgb.txt")
    depth_header, depth = read_list(full / "depth.txt")
    n = excerpt["frames"]
    # Only the first frames can start the excerpt; associating a bounded head keeps this linear.
    head = associate(rgb[: n + HEAD_EXTRA_FRAMES], depth[: n + HEAD_EXTRA_FRAMES])
    if not head:
        raise GetTumError(f"{name}: no colour frame of {full.name} has a depth frame within 20 ms")
    i0, j0 = rgb.index(head[0][0]), depth.index(head[0][1])
    if len(rgb) - i0 < n or len(depth) - j0 < n:
        raise GetTumError(
            f"{name}: {full.name} has {len(rgb) - i0} colour and {len(depth) - j0} depth frames "
            f"from its first pair, {n} needed"
        )
    return rgb_header, rgb[i0 : i0 + n], depth_header, depth[j0 : j0 + n]


def write_list(path: Path, header: list[str], rows: list) -> None:
    path.write_text(
        "".join(h + "\n" for h in header) + "".join(" ".join([r[1], *r[2]]) + "\n" for r in rows)
    )


def associate_lines(full: Path, rgb: list, depth: list, with_groundtruth: bool) -> str:
    """associate.txt as TUM associate.py writes it ('%f %s %f %s'): colour with depth, then (for
    rgb-depth-groundtruth) that result with groundtruth.txt, as `associate.py` run twice."""
    pairs = [(a[0], a[2] + [f"{b[0]:f}", *b[2]]) for a, b in associate(rgb, depth)]
    if with_groundtruth:
        _, gt = read_list(full / "groundtruth.txt")
        # associate.py reads a list into a dict: a repeated stamp keeps its last row.
        gt = list({r[0]: r for r in gt}.values())
        rows = [(p[0], p[0], p[1]) for p in pairs]
        pairs = [(a[0], a[2] + [f"{b[0]:f}", *b[2]]) for a, b in associate(rows, gt)]
    lines = []
    for stamp, rest in pairs:
        # Columns as associate.py prints them: first stamp %f, its fields, second stamp %f, fields.
        lines.append(f"{stamp:f} " + " ".join(rest) + "\n")
    return "".join(lines)


def cut_excerpt(full: Path, excerpt: dict, name: str, into: Path) -> Path:
    """Writes the excerpt folder `into/name` from the unpacked sequence `full`."""
    rgb_header, rgb, depth_header, depth = cut_rows(full, excerpt, name)
    out = into / name
    (out / "rgb").mkdir(parents=True)
    (out / "depth").mkdir()
    write_list(out / "rgb.txt", rgb_header, rgb)
    write_list(out / "depth.txt", depth_header, depth)
    for row in rgb + depth:
        rel = row[2][0] if row[2] else ""
        parts = PurePosixPath(rel).parts
        # A list names files inside rgb/ or depth/ only: nothing outside the sequence is copied.
        if len(parts) != 2 or parts[0] not in ("rgb", "depth") or parts[1] in ("..", "."):
            raise GetTumError(f"{name}: {full.name} lists '{rel}', not a file in rgb/ or depth/")
        if not (full / rel).is_file():
            raise GetTumError(f"{name}: {full.name} lists {rel}, which is not in the archive")
        shutil.copyfile(full / rel, out / rel)
    for f in excerpt["copies"]:
        if not (full / f).is_file():
            raise GetTumError(f"{name}: {full.name} has no {f}")
        shutil.copyfile(full / f, out / f)
    if excerpt["full_lists"]:
        shutil.copyfile(full / "rgb.txt", out / "rgb_full_sequence.txt")
        shutil.copyfile(full / "depth.txt", out / "depth_full_sequence.txt")
    if excerpt["associate"]:
        with_gt = excerpt["associate"] == "rgb-depth-groundtruth"
        (out / "associate.txt").write_text(associate_lines(full, rgb, depth, with_gt))
    return out


# ---- one sequence --------------------------------------------------------------------------------


def stamp_matches(folder: Path, exp: Expected) -> bool:
    try:
        stamp = json.loads((folder / STAMP_FILE).read_text())
    except (OSError, json.JSONDecodeError):
        return False
    return exp.sha256 is not None and stamp.get("sha256") == exp.sha256


def fetch_sequence(name: str, table: dict, root: Path, args, tmp: Path) -> Path:
    """Makes ROOT/tum-full/<tum_name> hold the verified sequence; returns that folder."""
    seq = table["sequences"][name]
    lock = read_lock(root)
    exp = expected_for(name, seq, lock, args.trust_on_first_use)
    target = root / FULL_DIR / seq["tum_name"]
    if not args.force and stamp_matches(target, exp):
        log(f"{name}: {target} already holds the verified archive (sha256 {exp.sha256[:12]}...)")
        return target
    archive = tmp / (seq["tum_name"] + ".tgz.part")
    url, sha = download(seq, archive, exp, name, args.quiet)
    size = archive.stat().st_size
    how = "matches the pinned" if exp.origin == "pinned" else f"matches the {exp.origin}"
    if exp.sha256 is None:
        how = "recorded (trust on first use: no published checksum to compare with)"
    log(f"{name}: {size} bytes, sha256 {sha} {how}")
    log(f"{name}: unpacking")
    folder = unpack(archive, tmp, seq["tum_name"])
    archive.unlink()
    stamp = {
        "sequence": name,
        "url": url,
        "bytes": size,
        "sha256": sha,
        "checked_against": exp.origin,
        "unpacked_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    (folder / STAMP_FILE).write_text(json.dumps(stamp, indent=2) + "\n")
    replace_dir(folder, target)
    if exp.sha256 is None:
        lock = read_lock(root)
        lock[name] = {
            "bytes": size,
            "sha256": sha,
            "url": url,
            "recorded_utc": stamp["unpacked_utc"],
        }
        write_json_atomic(root / LOCK_FILE, lock)
        log(f"{name}: size and sha256 recorded in {root / LOCK_FILE}")
    files = sum(1 for p in target.rglob("*") if p.is_file())
    log(f"{name}: unpacked into {target} ({files} files)")
    return target


def run(names: list[str], table: dict, root: Path, args, done: list[str]) -> None:
    """Fetches each sequence and cuts its excerpts, appending each excerpt written to `done`."""
    lock = read_lock(root)
    for name in names:  # a sequence that cannot be verified stops the run before any download
        expected_for(name, table["sequences"][name], lock, args.trust_on_first_use)
    for name in names:
        tmp = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=root))
        try:
            full = fetch_sequence(name, table, root, args, tmp)
            for ex_name, ex in table["excerpts"].items():
                if ex["sequence"] != name:
                    continue
                out = cut_excerpt(full, ex, ex_name, tmp)
                replace_dir(out, root / EXCERPTS_DIR / ex_name)
                log(
                    f"{name}: cut {ex_name} ({ex['frames']} colour + {ex['frames']} depth frames) "
                    f"into {root / EXCERPTS_DIR / ex_name}"
                )
                done.append(ex_name)
        except OSError as e:
            if e.errno == errno.ENOSPC:
                raise GetTumError(
                    f"{name}: the disk is full ({e.filename or root}); nothing was left in place"
                ) from e
            raise GetTumError(f"{name}: {e}") from e
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


# ---- command line --------------------------------------------------------------------------------


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog="get-tum.sh",
        description=(
            "Download TUM RGB-D sequences from the benchmark's site, check each archive's size and "
            "sha256 against a pinned table, unpack it into ROOT/tum-full/ and cut the excerpts "
            "make bench and make study read into ROOT/tum/ (the DATA folder they use when "
            "../shared/data is absent). Nothing half-written is left behind on a failure."
        ),
        epilog=(
            "With no SEQ: every sequence whose checksum is pinned (the ones make bench reads by "
            "default). Exit status: 0 done, 1 a download/check/unpack failed, 2 bad usage. "
            "Details: docs/data.md."
        ),
    )
    p.add_argument(
        "sequences",
        nargs="*",
        metavar="SEQ",
        help="sequence (fr1_xyz, fr1_desk, fr2_desk, fr1_360) or excerpt "
        "(fr1_xyz_first300, ...) name; an excerpt fetches its sequence",
    )
    p.add_argument(
        "--root",
        type=Path,
        default=DEFAULT_ROOT,
        help="where to write: ROOT/tum (excerpts), ROOT/tum-full (whole sequences), "
        "ROOT/tum-lock.json (default: %(default)s)",
    )
    p.add_argument(
        "--table",
        type=Path,
        default=DEFAULT_TABLE,
        help="the sequence table: URLs, pinned sizes and sha256, excerpts (default: %(default)s)",
    )
    p.add_argument(
        "--trust-on-first-use",
        action="store_true",
        help="accept a sequence with no pinned checksum and record its size and sha256 "
        "in ROOT/tum-lock.json; later downloads must match them",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="download again even if ROOT/tum-full already holds the verified archive",
    )
    p.add_argument("--list", action="store_true", help="print the table's sequences and exit")
    p.add_argument("--quiet", action="store_true", help="no download progress lines")
    return p.parse_args(argv)


def resolve_names(requested: list[str], table: dict) -> list[str]:
    seqs, excerpts = table["sequences"], table["excerpts"]
    if not requested:
        return [n for n, s in seqs.items() if s["sha256"]]
    names = []
    for r in requested:
        name = excerpts[r]["sequence"] if r in excerpts else r
        if name not in seqs:
            raise UsageError(
                f"unknown sequence '{r}'; known sequences: {', '.join(seqs)}; "
                f"excerpts: {', '.join(excerpts)}"
            )
        if name not in names:
            names.append(name)
    return names


def print_table(table: dict, root: Path) -> None:
    lock = read_lock(root) if root.is_dir() else {}
    for name, s in table["sequences"].items():
        if s["sha256"]:
            check = f"sha256 {s['sha256'][:16]}... pinned ({s['sha256_source']})"
        elif name in lock:
            check = f"sha256 {lock[name]['sha256'][:16]}... recorded in {LOCK_FILE}"
        else:
            check = "no pinned checksum: needs --trust-on-first-use"
        size = f"{s['bytes']} bytes" if s["bytes"] else "size unknown"
        cuts = [e for e, x in table["excerpts"].items() if x["sequence"] == name]
        print(f"{name}: {s['tum_name']}.tgz, {size}, {check}; excerpts: {', '.join(cuts) or '-'}")


def failed(done: list[str], root: Path) -> int:
    if done:
        log(f"completed before the failure, in {root / EXCERPTS_DIR}: {', '.join(done)}")
    return EXIT_FAILED


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    root = args.root.resolve()
    done: list[str] = []
    try:
        table = load_table(args.table)
        if args.list:
            print_table(table, root)
            return 0
        names = resolve_names(args.sequences, table)
        root.mkdir(parents=True, exist_ok=True)  # ROOT/tum appears with its first complete excerpt
        run(names, table, root, args, done)
    except UsageError as e:
        log(f"error: {e}")
        return EXIT_USAGE
    except GetTumError as e:
        log(f"error: {e}")
        return failed(done, root)
    except KeyboardInterrupt:
        log("interrupted; temporary files removed, nothing left half-written")
        return failed(done, root)
    log(f"done: {root / EXCERPTS_DIR} holds {', '.join(done) or 'no excerpts'}")
    shared = REPO.parent / "shared" / "data"
    if shared.is_dir():
        log(
            f"note: make bench / make study read {shared} while it exists; "
            f"DATA={root / EXCERPTS_DIR} make bench reads this folder"
        )
    else:
        log(f"make bench / make study read {root / EXCERPTS_DIR} by default")
    return 0


if __name__ == "__main__":
    sys.exit(main())
