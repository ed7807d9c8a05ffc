"""Reads quad-control's MCAP recordings with the `mcap` library, also when they are cut or damaged.

A complete file is read through the library's seeking reader with CRC validation (`read_complete`).
A file without its summary (quad-control killed, disk full) or with a damaged record is read in
streaming order record by record (`read_tolerant`): each top-level record is parsed by the library's
StreamReader with CRCs checked; a record cut by the end of the file stops the read, a damaged chunk
(CRC mismatch, bad compression) is skipped, and either is reported in `Recording.errors` with its
byte offset. Messages are decoded from JSON.
"""

from __future__ import annotations

import io
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import EndOfFile, McapError
from mcap.reader import make_reader
from mcap.records import Channel, DataEnd, Footer, Message, Schema
from mcap.stream_reader import StreamReader

MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEADER = struct.Struct("<BQ")  # opcode, content length (spec: Records)


@dataclass
class RecordedMessage:
    topic: str
    log_time_ns: int
    data: dict


@dataclass
class Recording:
    path: Path
    messages: list[RecordedMessage] = field(default_factory=list)
    channels: dict[int, str] = field(default_factory=dict)  # id -> topic
    schemas: dict[int, str] = field(default_factory=dict)  # id -> name
    complete: bool = False  # DataEnd and Footer read: the file was closed properly
    errors: list[str] = field(default_factory=list)
    bytes_read: int = 0  # how far the file was usable

    def topic(self, name: str) -> list[RecordedMessage]:
        return [m for m in self.messages if m.topic == name]

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for m in self.messages:
            out[m.topic] = out.get(m.topic, 0) + 1
        return out

    def span_s(self) -> float:
        if not self.messages:
            return 0.0
        times = [m.log_time_ns for m in self.messages]
        return (max(times) - min(times)) * 1e-9


def read_complete(path: Path) -> Recording:
    """The library's seeking reader, CRCs validated; raises McapError on any defect."""
    rec = Recording(Path(path))
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        if summary is None:
            raise McapError(f"{path}: no summary section (not closed properly)")
        rec.channels = {c.id: c.topic for c in summary.channels.values()}
        rec.schemas = {s.id: s.name for s in summary.schemas.values()}
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            rec.messages.append(
                RecordedMessage(channel.topic, message.log_time, json.loads(message.data))
            )
        rec.complete = True
        rec.bytes_read = Path(path).stat().st_size
    return rec


def read_tolerant(path: Path) -> Recording:
    """Streaming read that keeps what is readable; see the module docstring."""
    rec = Recording(Path(path))
    data = Path(path).read_bytes()
    if data[: len(MAGIC)] != MAGIC:
        rec.errors.append(f"{path}: not an MCAP file (bad magic {data[:8]!r})")
        return rec
    pos = len(MAGIC)
    while pos < len(data):
        if pos + _RECORD_HEADER.size > len(data):
            rec.errors.append(
                f"truncated at byte {pos}: record header cut ({len(data) - pos} bytes left)"
            )
            break
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        end = pos + _RECORD_HEADER.size + length
        if end > len(data):
            rec.errors.append(
                f"truncated at byte {pos}: record opcode 0x{opcode:02x} needs {length} bytes, "
                f"{len(data) - pos - _RECORD_HEADER.size} left"
            )
            break
        try:
            for r in StreamReader(
                io.BytesIO(data[pos:end]), skip_magic=True, validate_crcs=True
            ).records:
                _take(rec, r)
        except EndOfFile:
            pass  # the one whole record was consumed (its length was checked above); no next record
        except (McapError, ValueError, struct.error, EOFError) as e:
            rec.errors.append(f"damaged record opcode 0x{opcode:02x} at byte {pos} skipped: {e}")
        except Exception as e:  # noqa: BLE001 - zstd/json errors surface as various types
            rec.errors.append(
                f"damaged record opcode 0x{opcode:02x} at byte {pos} skipped: "
                f"{type(e).__name__}: {e}"
            )
        pos = end
        rec.bytes_read = pos
        if rec.complete:  # the Footer: what follows is the closing magic
            break
    return rec


def _take(rec: Recording, r) -> None:
    if isinstance(r, Schema):
        rec.schemas[r.id] = r.name
    elif isinstance(r, Channel):
        rec.channels[r.id] = r.topic
    elif isinstance(r, Message):
        topic = rec.channels.get(r.channel_id)
        if topic is None:
            rec.errors.append(f"message on unknown channel {r.channel_id} skipped")
            return
        rec.messages.append(RecordedMessage(topic, r.log_time, json.loads(r.data)))
    elif isinstance(r, DataEnd):
        pass
    elif isinstance(r, Footer):
        rec.complete = True


def read(path: Path) -> Recording:
    """Complete files through the seeking reader; anything else tolerantly (errors listed)."""
    try:
        return read_complete(path)
    except Exception as e:  # noqa: BLE001 - any defect: fall back to the streaming read
        rec = read_tolerant(path)
        rec.errors.insert(
            0, f"seeking read failed ({type(e).__name__}: {e}); read in streaming order"
        )
        return rec
