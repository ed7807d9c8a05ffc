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
# Keys of the version rule itself (protocol.oldest_decoded_version, ...): a projection to an older
# version removes them, so it reproduces that version's spec and hash exactly.
_VERSIONING_KEYS = {"oldest_decoded_version", "versions_doc", "since"}


class SpecError(ValueError):
    """The spec file is inconsistent (a bug in messages.json, never in peer input)."""


@dataclass(frozen=True)
class Spec:
    raw: dict

    @property
    def version(self) -> int:
        return self.raw["protocol"]["version"]

    @property
    def oldest_decoded_version(self) -> int:
        return self.raw["protocol"].get("oldest_decoded_version", self.version)

    @property
    def decoded_versions(self) -> range:
        """Every envelope version a decoder of this spec accepts."""
        return range(self.oldest_decoded_version, self.version + 1)

    def at_version(self, version: int) -> Spec:
        """The spec as it was at `version`: fields and structs marked 'since' a later version
        removed, the versioning keys removed, max_body_bytes recomputed. at_version(version) of
        the current version is the spec itself."""
        if version == self.version:
            return self
        if version not in self.decoded_versions:
            raise SpecError(f"version {version} is not decoded by this spec")

        def keep(node) -> bool:
            return not (isinstance(node, dict) and node.get("since", 0) > version)

        def project(node):
            if isinstance(node, dict):
                return {k: project(v) for k, v in node.items() if k not in _VERSIONING_KEYS}
            if isinstance(node, list):
                return [project(v) for v in node if keep(v)]
            return node

        raw = copy.deepcopy(self.raw)
        raw["structs"] = {k: v for k, v in raw["structs"].items() if keep(v)}
        raw = project(raw)
        raw["protocol"]["version"] = version
        old = Spec(raw)
        for m in raw["messages"]:
            m["max_body_bytes"] = old.message_max_body_bytes(m)
        return old

    @staticmethod
    def field_since(field: dict) -> int:
        """The version that added `field` (0: every version has it)."""
        return field.get("since", 0)

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
        for m in self.messages:
            since = [self.field_since(f) for f in m["fields"]]
            if since != sorted(since) or any(v > self.version for v in since):
                raise SpecError(f"{m['name']}: fields of a version step must come last, in order")
        codes = [e["code"] for e in self.raw["encodings"].values()]
        if len(set(codes)) != len(codes) or not all(0 <= c < 256 for c in codes):
            raise SpecError("encoding codes must be unique u8 values")


def load_spec(path: Path | str = SPEC_PATH) -> Spec:
    with open(path, encoding="utf-8") as f:
        return Spec(json.load(f))
