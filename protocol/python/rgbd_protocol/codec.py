"""Spec-driven codec of every message in protocol/spec/messages.json (pure Python, stdlib only).

Messages are plain dicts keyed by the spec's field names: enums by name (str), booleans as bool,
``bytes`` fields as bytes, fixed arrays as lists, structs as dicts, arrays as lists of dicts.
``to_view``/``from_view`` give the JSON view shared with the C++ tool (bytes as lowercase hex).

Decoding is the same two-pass procedure as the C++ codec so both report the same error for the
same hostile input: first the structure (truncation, length prefixes above their limit, trailing
bytes), then values (enums, booleans, ranges, finiteness, the named cross-field checks).
"""

from __future__ import annotations

import math
import re
import struct
import zlib
from dataclasses import dataclass, field

from .spec import ENVELOPE_HEADER_BYTES, ENVELOPE_TRAILER_BYTES, SCALAR_SIZES, Spec, load_spec

# Stable error names, identical to rgbdquad::protocol::to_string(DecodeError).
GARBAGE_SKIPPED = "garbage_skipped"
BAD_HEADER_CRC = "bad_header_crc"
UNSUPPORTED_VERSION = "unsupported_version"
UNKNOWN_MESSAGE_TYPE = "unknown_message_type"
RESERVED_NONZERO = "reserved_nonzero"
BODY_TOO_LARGE = "body_too_large"
BAD_BODY_CRC = "bad_body_crc"
TRUNCATED_BODY = "truncated_body"
LENGTH_TOO_LARGE = "length_too_large"
TRAILING_BYTES = "trailing_bytes"
INVALID_VALUE = "invalid_value"

# |q|^2 may differ from 1 by this much (1e-6 on |q|); same constant as the C++ codec.
UNIT_QUATERNION_TOLERANCE = 2e-6
_BYTES_PER_PIXEL = {"RGB8": 3, "DEPTH16": 2}
_FMT = {"u8": "<B", "u16": "<H", "u32": "<I", "u64": "<Q", "f32": "<f", "f64": "<d", "bool": "<B"}
_ARRAY_RE = re.compile(r"^(u8|u16|u32|u64|f32|f64)\[(\d+)\]$")
_STRING_RE = re.compile(r"^[\x20-\x7e]*$")


class DecodeFailure(Exception):
    """A body or envelope that breaks the spec: ``code`` is one of the names above."""

    def __init__(self, code: str, detail: str):
        super().__init__(f"{code}: {detail}")
        self.code = code
        self.detail = detail


class EncodeError(ValueError):
    """The message given to encode() breaks the spec (the reason names the field)."""


class _Truncated(Exception):
    pass


class _LengthTooLarge(Exception):
    pass


class _Reader:
    def __init__(self, data: bytes):
        self.data = memoryview(data)
        self.pos = 0

    def take(self, n: int) -> bytes:
        if n > len(self.data) - self.pos:
            raise _Truncated()
        out = bytes(self.data[self.pos : self.pos + n])
        self.pos += n
        return out

    def scalar(self, t: str):
        return struct.unpack(_FMT[t], self.take(SCALAR_SIZES[t]))[0]

    @property
    def remaining(self) -> int:
        return len(self.data) - self.pos


class Codec:
    """Encoder/decoder for one spec (the committed one by default)."""

    def __init__(self, spec: Spec | None = None):
        self.spec = spec or load_spec()
        self.spec.validate()
        self._enum_by_name = {e: self.spec.enum_values(e) for e in self.spec.raw["enums"]}
        self._enum_by_code = {
            e: {v: k for k, v in vals.items()} for e, vals in self._enum_by_name.items()
        }
        # Per decoded version, each message as that version defines it (docs/protocol.md,
        # "Versions and the schema hash").
        self._versions = {v: self.spec.at_version(v) for v in self.spec.decoded_versions}
        self.versions = self._versions  # read-only use by the stream decoder

    def message_at(self, name: str, version: int | None = None) -> dict:
        """Message `name` as envelope version `version` (default: ours) lays it out."""
        return self._versions[self.spec.version if version is None else version].message(name)

    def default_value(self, f: dict):
        """The friendly value a field takes when the body's version lacks it: zeros, False,
        empty, the first enum value."""
        t = f["type"]
        if t == "bool":
            return False
        if m := _ARRAY_RE.match(t):
            zero = 0.0 if m.group(1).startswith("f") else 0
            return [zero] * int(m.group(2))
        if t.startswith("enum:"):
            return next(iter(self._enum_by_name[t[5:]]))
        if t.startswith("struct:"):
            return {g["name"]: self.default_value(g) for g in self.spec.struct_fields(t[7:])}
        if t == "string":
            return ""
        if t == "bytes":
            return b""
        if t.startswith("array:"):
            return []
        return 0.0 if t.startswith("f") else 0

    # ------------------------------------------------------------------ structural decode
    def _read(self, f: dict, r: _Reader):
        t = f["type"]
        if t in SCALAR_SIZES:
            return r.scalar(t)
        if m := _ARRAY_RE.match(t):
            return [r.scalar(m.group(1)) for _ in range(int(m.group(2)))]
        if t.startswith("enum:"):
            return r.scalar(self.spec.raw["enums"][t[5:]]["type"])
        if t.startswith("struct:"):
            return self._read_fields(self.spec.struct_fields(t[7:]), r)
        if t in ("string", "bytes"):
            n = r.scalar("u16" if t == "string" else "u32")
            if n > self.spec.resolve_max(f["max_len"]):
                raise _LengthTooLarge(f"{f['name']}: length {n} above its limit")
            return r.take(n)
        if t.startswith("array:"):
            count = r.scalar("u32")
            if count > self.spec.resolve_max(f["max_len"]):
                raise _LengthTooLarge(f"{f['name']}: count {count} above its limit")
            item_fields = self.spec.struct_fields(t[6:])
            item_bytes = sum(self.spec.field_min_bytes(x) for x in item_fields)
            if count * item_bytes > r.remaining:
                raise _Truncated()
            return [self._read_fields(item_fields, r) for _ in range(count)]
        raise AssertionError(t)

    def _read_fields(self, fields: list[dict], r: _Reader) -> dict:
        return {f["name"]: self._read(f, r) for f in fields}

    # ------------------------------------------------------------------ values
    def _check_value(self, f: dict, v, path: str) -> None:  # noqa: C901 (one branch per spec type)
        """Raises EncodeError naming the field when a raw (wire-form) value breaks the spec."""
        t = f["type"]
        rng = f.get("range")
        if t == "bool":
            if v not in (0, 1):
                raise EncodeError(f"{path}: bool not 0 or 1")
        elif t.startswith("enum:"):
            if v not in self._enum_by_code[t[5:]]:
                raise EncodeError(f"{path}: unknown value")
        elif t in ("f32", "f64") or (_ARRAY_RE.match(t) and t.startswith("f")):
            for x in v if isinstance(v, list) else [v]:
                lo, hi = rng if rng else (-math.inf, math.inf)
                if not (math.isfinite(x) and lo <= x <= hi):
                    raise EncodeError(f"{path}: {x} outside [{lo}, {hi}] or not finite")
        elif t in SCALAR_SIZES or _ARRAY_RE.match(t):
            m = _ARRAY_RE.match(t)
            if m and (not isinstance(v, (list, tuple)) or len(v) != int(m.group(2))):
                raise EncodeError(f"{path}: expected {m.group(2)} values")
            bits = 8 * SCALAR_SIZES[m.group(1) if m else t]
            for x in v if isinstance(v, (list, tuple)) else [v]:
                if not (isinstance(x, int) and 0 <= x < (1 << bits)):
                    raise EncodeError(f"{path}: {x} does not fit its wire type")
                if rng and not (rng[0] <= x <= rng[1]):
                    raise EncodeError(f"{path}: {x} outside [{rng[0]}, {rng[1]}]")
        elif t == "string":
            if len(v) > self.spec.resolve_max(f["max_len"]) or not _STRING_RE.match(
                v.decode("latin-1")
            ):
                raise EncodeError(f"{path}: not printable ASCII within its length limit")
        elif t == "bytes":
            if len(v) > self.spec.resolve_max(f["max_len"]):
                raise EncodeError(f"{path}: too long")
        elif t.startswith("struct:"):
            self._check_struct(t[7:], v, path)
        elif t.startswith("array:"):
            if len(v) > self.spec.resolve_max(f["max_len"]):
                raise EncodeError(f"{path}: too many items")
            for item in v:
                self._check_struct(t[6:], item, path)

    def _check_struct(self, name: str, v: dict, path: str) -> None:
        self._check_fields(self.spec.struct_fields(name), v, path)
        self._run_checks(self.spec.struct_checks(name), v, path)

    def _check_fields(self, fields: list[dict], v: dict, path: str) -> None:
        for f in fields:
            self._check_value(
                f, v[f["name"]], f"{path}{f['name']}" if not path else f"{path}.{f['name']}"
            )

    def _run_checks(self, checks: list[str], v: dict, path: str) -> None:  # noqa: C901 (one per check)
        name = self._enum_by_code
        for check in checks:
            if check == "encoding_allows_pixel_format":
                enc = name["Encoding"][v["encoding"]]
                fmt = name["PixelFormat"][v["pixel_format"]]
                if fmt not in self.spec.raw["encodings"][enc]["pixel_formats"]:
                    raise EncodeError(f"{path}.encoding: does not carry this pixel_format")
            elif check == "raw_payload_size":
                if name["Encoding"][v["encoding"]] == "RAW":
                    bpp = _BYTES_PER_PIXEL[name["PixelFormat"][v["pixel_format"]]]
                    if len(v["payload"]) != v["width"] * v["height"] * bpp:
                        raise EncodeError(f"{path}.payload: RAW size != width*height*bpp")
            elif check == "unit_quaternion":
                x, y, z, w = v["q_xyzw"]
                if not abs(x * x + y * y + z * z + w * w - 1.0) <= UNIT_QUATERNION_TOLERANCE:
                    raise EncodeError(f"{path}.q_xyzw: not a unit quaternion")
            elif check == "stream_kind_matches_pixel_format":
                pair = (
                    name["StreamKind"][v["stream_kind"]],
                    name["PixelFormat"][v["pixel_format"]],
                )
                if pair not in (("RGB", "RGB8"), ("DEPTH", "DEPTH16")):
                    raise EncodeError("pixel_format: does not match stream_kind")
            elif check == "rgbd_pixel_formats":
                if name["PixelFormat"][v["rgb"]["pixel_format"]] != "RGB8":
                    raise EncodeError("rgb.pixel_format: must be RGB8")
                if name["PixelFormat"][v["depth"]["pixel_format"]] != "DEPTH16":
                    raise EncodeError("depth.pixel_format: must be DEPTH16")
            elif check == "map_cells_size":
                if len(v["cells"]) != v["width_cells"] * v["height_cells"]:
                    raise EncodeError("cells: size != width_cells*height_cells")
            else:
                raise AssertionError(f"check {check!r} in the spec has no implementation")

    def _validate_message(self, message: dict, wire: dict) -> None:
        self._check_fields(message["fields"], wire, "")
        self._run_checks(message.get("checks", []), wire, "")

    # ------------------------------------------------------------------ wire <-> friendly values
    def _to_friendly(self, f: dict, v):
        t = f["type"]
        if t == "bool":
            return bool(v)
        if t.startswith("enum:"):
            return self._enum_by_code[t[5:]][v]
        if t == "string":
            return v.decode("ascii")
        if t.startswith("struct:"):
            return {
                g["name"]: self._to_friendly(g, v[g["name"]])
                for g in self.spec.struct_fields(t[7:])
            }
        if t.startswith("array:"):
            item_fields = self.spec.struct_fields(t[6:])
            return [
                {g["name"]: self._to_friendly(g, item[g["name"]]) for g in item_fields}
                for item in v
            ]
        return v

    def _to_wire(self, f: dict, v, path: str):
        t = f["type"]
        try:
            if t == "bool":
                if not isinstance(v, bool):
                    raise EncodeError(f"{path}: expected a bool")
                return int(v)
            if t.startswith("enum:"):
                if isinstance(v, int) and 0 <= v <= 255:
                    return v
                return self._enum_by_name[t[5:]][v]
            if t == "string":
                return v.encode("latin-1") if isinstance(v, str) else bytes(v)
            if t == "bytes":
                return bytes(v)
            if t.startswith("struct:"):
                return self._fields_to_wire(self.spec.struct_fields(t[7:]), v, path)
            if t.startswith("array:"):
                item_fields = self.spec.struct_fields(t[6:])
                return [self._fields_to_wire(item_fields, item, path) for item in v]
            if m := _ARRAY_RE.match(t):
                if len(v) != int(m.group(2)):
                    raise EncodeError(f"{path}: expected {m.group(2)} values")
                return [float(x) if m.group(1).startswith("f") else int(x) for x in v]
            if t.startswith("f"):
                return float(v)
            if isinstance(v, bool) or not isinstance(v, int):
                raise EncodeError(f"{path}: expected an integer")
            return v
        except (KeyError, TypeError, UnicodeEncodeError) as e:
            raise EncodeError(f"{path}: {e!r}") from None

    def _fields_to_wire(self, fields: list[dict], values: dict, path: str) -> dict:
        if not isinstance(values, dict):
            raise EncodeError(f"{path}: expected an object")
        # A field a version step added may be left out: it is sent as its default (not valid).
        missing = [f["name"] for f in fields if f["name"] not in values and "since" not in f]
        if missing:
            raise EncodeError(f"{path}: missing field(s) {missing}")
        return {
            f["name"]: self._to_wire(
                f,
                values[f["name"]] if f["name"] in values else self.default_value(f),
                f"{path}.{f['name']}" if path else f["name"],
            )
            for f in fields
        }

    # ------------------------------------------------------------------ structural encode
    def _write(self, f: dict, v, out: bytearray) -> None:
        t = f["type"]
        if t in SCALAR_SIZES:
            out += struct.pack(_FMT[t], v)
        elif m := _ARRAY_RE.match(t):
            for x in v:
                out += struct.pack(_FMT[m.group(1)], x)
        elif t.startswith("enum:"):
            out += struct.pack(_FMT[self.spec.raw["enums"][t[5:]]["type"]], v)
        elif t.startswith("struct:"):
            self._write_fields(self.spec.struct_fields(t[7:]), v, out)
        elif t in ("string", "bytes"):
            out += struct.pack("<H" if t == "string" else "<I", len(v))
            out += v
        elif t.startswith("array:"):
            out += struct.pack("<I", len(v))
            for item in v:
                self._write_fields(self.spec.struct_fields(t[6:]), item, out)

    def _write_fields(self, fields: list[dict], values: dict, out: bytearray) -> None:
        for f in fields:
            self._write(f, values[f["name"]], out)

    # ------------------------------------------------------------------ public API
    def encode_body(
        self, name: str, fields: dict, *, validate: bool = True, version: int | None = None
    ) -> bytes:
        """Body bytes of message `name` as `version` (default: ours) lays it out; raises
        EncodeError when `fields` break the spec. Fields that version lacks are left out.

        validate=False writes values the spec forbids (enum numbers, NaN, ...): only for forging
        the hostile golden vectors.
        """
        if version is not None and version not in self._versions:
            raise EncodeError(f"version {version} is not one this codec writes")
        try:
            message = self.message_at(name, version)
        except KeyError:
            raise EncodeError(f"unknown message {name!r}") from None
        wire = self._fields_to_wire(message["fields"], fields, "")
        if validate:
            self._validate_message(message, wire)
        out = bytearray()
        self._write_fields(message["fields"], wire, out)
        return bytes(out)

    def encode(self, name: str, fields: dict, *, version: int | None = None) -> bytes:
        """Full envelope (header, body, trailer) of message `name`, in envelope version `version`
        (default: ours; an older one to answer a peer that speaks it)."""
        body = self.encode_body(name, fields, version=version)
        return self.wrap(self.spec.message(name)["id"], body, version=version)

    def wrap(
        self, type_id: int, body: bytes, *, version: int | None = None, reserved: int = 0
    ) -> bytes:
        """Envelope around an already-encoded body (tests use the keywords to forge headers)."""
        header = self.spec.magic + struct.pack(
            "<BBHI", self.spec.version if version is None else version, type_id, reserved, len(body)
        )
        return (
            header
            + struct.pack("<I", zlib.crc32(header))
            + body
            + struct.pack("<I", zlib.crc32(body))
        )

    def decode_body(
        self, type_id: int, body: bytes, version: int | None = None
    ) -> tuple[str, dict]:
        """(message name, fields) of one body of envelope version `version` (default: ours);
        fields that version lacks come back as their defaults. Raises DecodeFailure."""
        spec = self._versions.get(self.spec.version if version is None else version)
        if spec is None:
            raise DecodeFailure(UNSUPPORTED_VERSION, f"version {version}")
        message = spec.message_by_id(type_id)
        if message is None:
            raise DecodeFailure(UNKNOWN_MESSAGE_TYPE, f"message type {type_id} is not in the spec")
        r = _Reader(body)
        try:
            wire = self._read_fields(message["fields"], r)
        except _LengthTooLarge as e:
            raise DecodeFailure(LENGTH_TOO_LARGE, str(e)) from None
        except _Truncated:
            raise DecodeFailure(TRUNCATED_BODY, "body ends inside its fields") from None
        if r.remaining:
            raise DecodeFailure(TRAILING_BYTES, f"{r.remaining} bytes after the last field")
        try:
            self._validate_message(message, wire)
        except EncodeError as e:
            raise DecodeFailure(INVALID_VALUE, str(e)) from None
        return message["name"], {
            f["name"]: self._to_friendly(f, wire[f["name"]])
            if f["name"] in wire
            else self.default_value(f)
            for f in self.spec.message(message["name"])["fields"]
        }

    def incompatibility(self, fields: dict) -> str:
        """'' when a Handshake/SlamHello's version is one we decode and its schema hash is that
        version's, else the reason."""
        version = fields["protocol_version"]
        spec = self._versions.get(version)
        if spec is None:
            lo, hi = self.spec.oldest_decoded_version, self.spec.version
            return f"protocol version mismatch: peer {version}, ours {lo}..{hi}"
        if fields["schema_hash"] != spec.schema_hash:
            return (
                f"schema hash mismatch: peer 0x{fields['schema_hash']:016x}, "
                f"ours 0x{spec.schema_hash:016x} for version {version}"
            )
        return ""

    # ------------------------------------------------------------------ JSON view
    def to_view(self, name: str, fields: dict) -> dict:
        """The JSON view shared with the C++ tool: bytes fields as lowercase hex."""

        def conv(v):
            if isinstance(v, (bytes, bytearray)):
                return bytes(v).hex()
            if isinstance(v, dict):
                return {k: conv(x) for k, x in v.items()}
            if isinstance(v, list):
                return [conv(x) for x in v]
            return v

        return {"type": name, "fields": conv(fields)}

    def from_view(self, view: dict) -> tuple[str, dict]:
        message = self.spec.message(view["type"])

        def conv(fields: list[dict], values: dict) -> dict:
            out = {}
            for f in fields:
                v = values[f["name"]]
                t = f["type"]
                if t == "bytes":
                    v = bytes.fromhex(v)
                elif t.startswith("struct:"):
                    v = conv(self.spec.struct_fields(t[7:]), v)
                elif t.startswith("array:"):
                    v = [conv(self.spec.struct_fields(t[6:]), item) for item in v]
                out[f["name"]] = v
            return out

        return message["name"], conv(message["fields"], view["fields"])


@dataclass
class Event:
    """One result of StreamDecoder.next(): kind is 'need_more', 'message' or 'error'."""

    kind: str
    name: str = ""
    fields: dict = field(default_factory=dict)
    error: str = ""
    detail: str = ""
    bytes_discarded: int = 0
    version: int = 0  # envelope version of a message (a receiver answers a peer in it)


class StreamDecoder:
    """Incremental decoder of a stream of envelopes; same behaviour as the C++ StreamDecoder.

    feed() bytes, then call next() until it returns kind 'need_more'.
    """

    def __init__(self, codec: Codec | None = None, max_body_bytes: int = 0):
        self.codec = codec or Codec()
        self.max_body_bytes = max_body_bytes
        self._buf = bytearray()
        self._magic = self.codec.spec.magic

    def feed(self, data: bytes) -> None:
        self._buf += data

    @property
    def buffered_bytes(self) -> int:
        return len(self._buf)

    def _discard_to_next_magic(self, start: int) -> int:
        # First i >= start where the magic starts, or a prefix of it ends the buffer.
        buf, magic = self._buf, self._magic
        i = buf.find(magic, start)
        if i < 0:
            i = len(buf)
            for k in range(len(magic) - 1, 0, -1):  # longest partial first = smallest offset
                if len(buf) - k >= start and buf[len(buf) - k :] == magic[:k]:
                    i = len(buf) - k
                    break
        del buf[:i]
        return i

    def next(self) -> Event:
        buf = self._buf
        if not buf:
            return Event("need_more")
        skipped = self._discard_to_next_magic(0)
        if skipped:
            return Event(
                "error",
                error=GARBAGE_SKIPPED,
                detail=f"{skipped} bytes before a magic",
                bytes_discarded=skipped,
            )
        if len(buf) < ENVELOPE_HEADER_BYTES:
            return Event("need_more")
        version, type_id, reserved, body_length, header_crc = struct.unpack_from("<BBHII", buf, 4)

        def header_error(code: str, detail: str) -> Event:
            return Event(
                "error", error=code, detail=detail, bytes_discarded=self._discard_to_next_magic(1)
            )

        if zlib.crc32(bytes(buf[:12])) != header_crc:
            return header_error(BAD_HEADER_CRC, "header CRC")
        if version not in self.codec.spec.decoded_versions:
            return header_error(UNSUPPORTED_VERSION, f"version {version}")
        message = self.codec.versions[version].message_by_id(type_id)
        if message is None:
            return header_error(UNKNOWN_MESSAGE_TYPE, f"type {type_id}")
        if reserved:
            return header_error(RESERVED_NONZERO, "reserved bits set")
        cap = message["max_body_bytes"]
        if self.max_body_bytes:
            cap = min(cap, self.max_body_bytes)
        if body_length > cap:
            return header_error(BODY_TOO_LARGE, f"body_length {body_length} > {cap}")
        total = ENVELOPE_HEADER_BYTES + body_length + ENVELOPE_TRAILER_BYTES
        if len(buf) < total:
            return Event("need_more")
        body = bytes(buf[ENVELOPE_HEADER_BYTES : ENVELOPE_HEADER_BYTES + body_length])
        (body_crc,) = struct.unpack_from("<I", buf, ENVELOPE_HEADER_BYTES + body_length)
        del buf[:total]
        if zlib.crc32(body) != body_crc:
            return Event("error", error=BAD_BODY_CRC, detail="body CRC", bytes_discarded=total)
        try:
            name, fields = self.codec.decode_body(type_id, body, version)
        except DecodeFailure as e:
            return Event("error", error=e.code, detail=e.detail, bytes_discarded=total)
        return Event("message", name=name, fields=fields, version=version)

    def drain(self) -> list[Event]:
        """Every event until need_more."""
        events = []
        while (e := self.next()).kind != "need_more":
            events.append(e)
        return events


def event_view(codec: Codec, e: Event) -> dict:
    """The event as the C++ tool prints it (without 'detail', which is free text)."""
    if e.kind == "message":
        return {"event": "message", "message": codec.to_view(e.name, e.fields)}
    return {"event": "error", "error": e.error, "bytes_discarded": e.bytes_discarded}


def normalize_events(events: list[dict]) -> list[dict]:
    """Merges each garbage_skipped into a directly preceding error (adding the bytes dropped).

    How a run of bad bytes is reported depends on how the stream was cut into reads (a decoder fed
    byte by byte reports the garbage after a bad header as it arrives); after this merge the
    events are the same for every chunking, which is how the golden vectors are compared.
    """
    out: list[dict] = []
    for e in events:
        if e.get("error") == GARBAGE_SKIPPED and out and out[-1]["event"] == "error":
            out[-1] = dict(
                out[-1], bytes_discarded=out[-1]["bytes_discarded"] + e["bytes_discarded"]
            )
        else:
            out.append(dict(e))
    return out
