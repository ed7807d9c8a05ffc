"""Loads protocol/spec/messages.json, the one definition of every message, and derives from it what
both codecs need: the schema hash, enum tables, fixed/maximum sizes of every struct and message.

Pure standard library so that the C++ header generator (protocol/tools/gen_cpp.py) can run with the
system python3 as well as from the project venv.
"""

from __future__ import annotations

import copy
import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path

SPEC_PATH = Path(__file__).resolve().parents[2] / "spec" / "messages.json"

# Sizes in bytes of the scalar wire types (all little-endian).
SCALAR_SIZES = {"u8": 1, "u16": 2, "u32": 4, "u64": 8, "f32": 4, "f64": 8, "bool": 1}
ENVELOPE_HEADER_BYTES = 16
ENVELOPE_TRAILER_BYTES = 4
LENGTH_PREFIX_BYTES = {"string": 2, "bytes": 4, "array": 4}

_ARRAY_RE = re.compile(r"^(u8|u16|u32|u64|f32|f64)\[(\d+)\]$")
# Keys that document but do not change the wire format: excluded from the schema hash.
_DOC_KEYS = {"doc", "unit", "direction", "about"}


class SpecError(ValueError):
    """The spec file is inconsistent (a bug in messages.json, never in peer input)."""


@dataclass(frozen=True)
class Spec:
    raw: dict

    @property
    def version(self) -> int:
        return self.raw["protocol"]["version"]

    @property
    def magic(self) -> bytes:
        return self.raw["protocol"]["magic"].encode("ascii")

    def limit(self, name: str) -> int:
        return self.raw["limits"][name]["value"]

    def resolve_max(self, value) -> int:
        return self.limit(value) if isinstance(value, str) else int(value)

    def enum_values(self, name: str) -> dict[str, int]:
        enum = self.raw["enums"][name]
        if "registry" in enum:
            return {k: v["code"] for k, v in self.raw[enum["registry"]].items()}
        return dict(enum["values"])

    @property
    def messages(self) -> list[dict]:
        return self.raw["messages"]

    def message(self, name: str) -> dict:
        for m in self.messages:
            if m["name"] == name:
                return m
        raise KeyError(name)

    def message_by_id(self, type_id: int) -> dict | None:
        for m in self.messages:
            if m["id"] == type_id:
                return m
        return None

    def struct_fields(self, name: str) -> list[dict]:
        return self.raw["structs"][name]["fields"]

    def struct_checks(self, name: str) -> list[str]:
        return self.raw["structs"][name].get("checks", [])

    def field_min_bytes(self, field: dict) -> int:
        t = field["type"]
        if t in SCALAR_SIZES:
            return SCALAR_SIZES[t]
        if m := _ARRAY_RE.match(t):
            return SCALAR_SIZES[m.group(1)] * int(m.group(2))
        if t.startswith("enum:"):
            return SCALAR_SIZES[self.raw["enums"][t[5:]]["type"]]
        if t.startswith("struct:"):
            return sum(self.field_min_bytes(f) for f in self.struct_fields(t[7:]))
        if t in ("string", "bytes") or t.startswith("array:"):
            return LENGTH_PREFIX_BYTES[t.split(":")[0]]
        raise SpecError(f"unknown type {t!r}")

    def field_max_bytes(self, field: dict) -> int:
        t = field["type"]
        if t in ("string", "bytes"):
            return LENGTH_PREFIX_BYTES[t] + self.resolve_max(field["max_len"])
        if t.startswith("array:"):
            item = sum(self.field_max_bytes(f) for f in self.struct_fields(t[6:]))
            return LENGTH_PREFIX_BYTES["array"] + item * self.resolve_max(field["max_len"])
        if t.startswith("struct:"):
            return sum(self.field_max_bytes(f) for f in self.struct_fields(t[7:]))
        return self.field_min_bytes(field)

    def message_max_body_bytes(self, message: dict) -> int:
        return sum(self.field_max_bytes(f) for f in message["fields"])

    def message_min_body_bytes(self, message: dict) -> int:
        return sum(self.field_min_bytes(f) for f in message["fields"])

    def canonical_json(self) -> str:
        """The wire-relevant part of the spec, canonicalised: sorted keys, no whitespace, no docs.

        The encoding registry is left out on purpose: encodings are negotiated per stream by the
        handshake, so registering a new one must not make every older peer refuse the link.
        """
        wire = {
            k: copy.deepcopy(self.raw[k])
            for k in ("protocol", "limits", "enums", "structs", "messages")
        }

        def strip(node):
            if isinstance(node, dict):
                return {k: strip(v) for k, v in node.items() if k not in _DOC_KEYS}
            if isinstance(node, list):
                return [strip(v) for v in node]
            return node

        return json.dumps(strip(wire), sort_keys=True, separators=(",", ":"), ensure_ascii=True)

    @property
    def schema_hash(self) -> int:
        digest = hashlib.sha256(self.canonical_json().encode("ascii")).digest()
        return int.from_bytes(digest[:8], "little")

    def validate(self) -> None:
        """Raises SpecError when the spec contradicts itself."""
        ids = [m["id"] for m in self.messages]
        if len(set(ids)) != len(ids) or not all(0 < i < 256 for i in ids):
            raise SpecError("message ids must be unique and in 1..255")
        for m in self.messages:
            computed = self.message_max_body_bytes(m)
            if m["max_body_bytes"] != computed:
                raise SpecError(f"{m['name']}: max_body_bytes {m['max_body_bytes']} != {computed}")
        codes = [e["code"] for e in self.raw["encodings"].values()]
        if len(set(codes)) != len(codes) or not all(0 <= c < 256 for c in codes):
            raise SpecError("encoding codes must be unique u8 values")


def load_spec(path: Path | str = SPEC_PATH) -> Spec:
    with open(path, encoding="utf-8") as f:
        return Spec(json.load(f))
