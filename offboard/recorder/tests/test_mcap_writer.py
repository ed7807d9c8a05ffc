"""rgbd_mcap (offboard/recorder) files read by the Python `mcap` library: complete, cut, damaged,
full disk.

The C++ writer is driven through build/bin/mcap-sample (MCAP_SAMPLE_BIN overrides).
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from flight_recording.reader import read, read_complete, read_tolerant
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.stream_reader import CRCValidationError, StreamReader

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("MCAP_SAMPLE_BIN", ROOT / "build" / "bin" / "mcap-sample"))

pytestmark = pytest.mark.skipif(not BIN.exists(), reason=f"{BIN} not built (make build)")


def sample(path: Path, n: int, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(BIN), str(path), str(n), *args],
        capture_output=True,
        text=True,
        check=check,
        timeout=60,
    )


@pytest.mark.parametrize(
    "args", [[], ["--no-zstd"], ["--flush-every", "7"], ["--chunk-bytes", "1024"]]
)
def test_complete_file_reads_with_crcs_summary_and_index(tmp_path, args):
    f = tmp_path / "a.mcap"
    sample(f, 1001, *args)
    with open(f, "rb") as fh:
        reader = make_reader(fh, validate_crcs=True)
        summary = reader.get_summary()
        assert summary.statistics.message_count == 1001
        assert summary.statistics.channel_message_counts == {1: 501, 2: 500}
        assert {c.topic for c in summary.channels.values()} == {"/a", "/b"}
        assert summary.channels[1].metadata == {"k": "v"}
        assert len(summary.chunk_indexes) == summary.statistics.chunk_count >= 1
        # Index-driven read (chunk indexes + message indexes), in log-time order.
        got = [m.log_time for _s, _c, m in reader.iter_messages(topics=["/b"])]
        assert got == [i * 1_000_000 for i in range(1, 1001, 2)]
    rec = read_complete(f)
    assert [m.data["i"] for m in rec.messages] == list(range(1001))
    # The streaming read of a sound file finds the same, with no error.
    tolerant = read_tolerant(f)
    assert tolerant.complete and tolerant.errors == []
    assert [m.data["i"] for m in tolerant.messages] == list(range(1001))


def test_file_without_summary_reads_in_streaming_mode_up_to_the_last_flush(tmp_path):
    f = tmp_path / "killed.mcap"
    sample(f, 500, "--flush-every", "100", "--no-close")
    with open(f, "rb") as fh, pytest.raises(McapError):
        list(make_reader(fh).iter_messages())  # the seeking reader needs the footer
    rec = read(f)
    assert not rec.complete
    assert [m.data["i"] for m in rec.messages] == list(range(500))
    assert len(rec.errors) == 1 and "streaming order" in rec.errors[0], rec.errors


def test_truncated_file_gives_a_clear_error_and_every_whole_chunk(tmp_path):
    f = tmp_path / "cut.mcap"
    sample(f, 1000, "--flush-every", "100", "--no-zstd")
    data = f.read_bytes()
    cut = tmp_path / "cut2.mcap"
    cut.write_bytes(data[: len(data) // 2])
    # The library's streaming reader stops with an exception at the cut ...
    n = 0
    # (any exception: its type depends on where the cut falls in a record)
    with open(cut, "rb") as fh, pytest.raises(Exception):  # noqa: B017
        for r in StreamReader(fh, validate_crcs=True).records:
            n += type(r).__name__ == "Message"
    # ... ours keeps the whole chunks before it and says where it stopped.
    rec = read_tolerant(cut)
    got = [m.data["i"] for m in rec.messages]
    assert got == list(range(len(got))) and 400 <= len(got) < 1000
    assert n == len(got)
    assert any(e.startswith("truncated at byte") for e in rec.errors), rec.errors


def test_corrupt_chunk_is_skipped_with_its_offset_and_the_rest_is_read(tmp_path):
    f = tmp_path / "bad.mcap"
    sample(f, 1000, "--flush-every", "100", "--no-zstd")
    data = bytearray(f.read_bytes())
    where = data.find(b'{"i":250}')
    data[where + 5] = ord("7")  # one byte inside the third chunk: its CRC no longer matches
    f.write_bytes(bytes(data))
    with pytest.raises((McapError, CRCValidationError)):
        read_complete(f)
    rec = read(f)
    got = [m.data["i"] for m in rec.messages]
    assert got == list(range(200)) + list(range(300, 1000))
    assert any("damaged record opcode 0x06" in e for e in rec.errors), rec.errors


def test_not_an_mcap_file_is_named(tmp_path):
    f = tmp_path / "x.mcap"
    f.write_bytes(b"hello world, not mcap")
    rec = read(f)
    assert not rec.messages and any("not an MCAP file" in e for e in rec.errors)


def test_full_disk_fails_the_writer_with_the_cause_and_leaves_a_readable_prefix(tmp_path):
    f = tmp_path / "full.mcap"
    p = sample(f, 100000, "--flush-every", "100", "--fsize-limit", "65536", check=False)
    assert p.returncode == 3
    assert "File too large" in p.stderr
    assert f.stat().st_size <= 65536
    rec = read(f)
    got = [m.data["i"] for m in rec.messages]
    assert len(got) >= 100 and got == list(range(len(got)))
