"""Ground-station codec of the control link (ground station -> WiFi bridge -> ATmega328P firmware).

The link is defined once in protocol/control/control_spec.json; its ranges, field order, status
codes, schema version and the Reply type come from control_spec_generated.py (generated from the
spec by protocol/control/tools/gen_control.py, re-exported here; nothing is redefined). Proven
against the golden vectors in protocol/control/vectors/control_vectors.json, which the firmware
core and the C++ ground-station codec replay too. See docs/protocol-control.md.

    key = bytes.fromhex(config["control_key_hex"])      # the craft's 16-byte secret
    seqs = SequenceCounter()
    line = build_control_request(key, seqs.next(), arm=True, roll_us=1500, pitch_us=1500,
                                 thr_us=1000, yaw_us=1500)
    reply = parse_reply(reply_line)                       # Reply(status=200, state="armed", ...)

Pure functions plus one small counter class; thread-safe except SequenceCounter (one per sender).
"""

from __future__ import annotations

import json
import re
import struct

from .control_spec_generated import (  # noqa: F401  (re-exported: the link's constants and types)
    BRIDGE_BAUD,
    CHANNEL_MAX_US,
    CHANNEL_MIN_US,
    CONTROL_LINK_VERSION,
    CONTROL_PATH,
    FIELDS,
    KEY_BYTES,
    MAX_REPLY_BYTES,
    MAX_REQUEST_BYTES,
    RANGES,
    REPLY_FIELDS,
    STATES,
    STATUS_PATH,
    STATUS_REASONS,
    Reply,
    Status,
)

_MASK64 = (1 << 64) - 1


def _rotl(x: int, b: int) -> int:
    return ((x << b) | (x >> (64 - b))) & _MASK64


def _sipround(v0: int, v1: int, v2: int, v3: int) -> tuple[int, int, int, int]:
    v0 = (v0 + v1) & _MASK64
    v1 = _rotl(v1, 13)
    v1 ^= v0
    v0 = _rotl(v0, 32)
    v2 = (v2 + v3) & _MASK64
    v3 = _rotl(v3, 16)
    v3 ^= v2
    v0 = (v0 + v3) & _MASK64
    v3 = _rotl(v3, 21)
    v3 ^= v0
    v2 = (v2 + v1) & _MASK64
    v1 = _rotl(v1, 17)
    v1 ^= v2
    v2 = _rotl(v2, 32)
    return v0, v1, v2, v3


def siphash24(key: bytes, msg: bytes) -> bytes:
    """SipHash-2-4 of msg under a 16-byte key; returns the 8 tag bytes in wire order."""
    if len(key) != 16:
        raise ValueError(f"SipHash key must be 16 bytes, got {len(key)}")
    k0, k1 = struct.unpack("<QQ", key)
    v0 = 0x736F6D6570736575 ^ k0
    v1 = 0x646F72616E646F6D ^ k1
    v2 = 0x6C7967656E657261 ^ k0
    v3 = 0x7465646279746573 ^ k1
    full = len(msg) // 8 * 8
    for i in range(0, full, 8):
        (m,) = struct.unpack_from("<Q", msg, i)
        v3 ^= m
        v0, v1, v2, v3 = _sipround(v0, v1, v2, v3)
        v0, v1, v2, v3 = _sipround(v0, v1, v2, v3)
        v0 ^= m
    b = (len(msg) & 0xFF) << 56
    for i, byte in enumerate(msg[full:]):
        b |= byte << (8 * i)
    v3 ^= b
    v0, v1, v2, v3 = _sipround(v0, v1, v2, v3)
    v0, v1, v2, v3 = _sipround(v0, v1, v2, v3)
    v0 ^= b
    v2 ^= 0xFF
    for _ in range(4):
        v0, v1, v2, v3 = _sipround(v0, v1, v2, v3)
    return struct.pack("<Q", v0 ^ v1 ^ v2 ^ v3)


def _check_range(name: str, value: int) -> None:
    lo, hi = RANGES[name]
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ValueError(f"{name}={value!r} outside its range [{lo}, {hi}]")


def build_control_request(
    key: bytes, seq: int, arm: bool, roll_us: int, pitch_us: int, thr_us: int, yaw_us: int
) -> str:
    """Returns the request line (without newline) for PUT /control, authenticated under key.

    Raises ValueError when a value is outside its protocol range or the key has the wrong length.
    """
    if len(key) != KEY_BYTES:
        raise ValueError(f"control key must be {KEY_BYTES} bytes, got {len(key)}")
    values = {
        "seq": seq,
        "arm": 1 if arm else 0,
        "roll": roll_us,
        "pitch": pitch_us,
        "thr": thr_us,
        "yaw": yaw_us,
    }
    for name in FIELDS:
        _check_range(name, values[name])
    query = "&".join(f"{name}={values[name]}" for name in FIELDS)
    signed = f"PUT {CONTROL_PATH}?{query}"
    return f"{signed}&mac={siphash24(key, signed.encode('ascii')).hex()}"


def build_status_request() -> str:
    """Returns the request line (without newline) for GET /status."""
    return f"GET {STATUS_PATH}"


class SequenceCounter:
    """Strictly increasing sequence numbers for one craft's commands (not thread-safe).

    Start above the last sequence number the craft accepted (its replies carry it), e.g. after a
    ground-station restart: SequenceCounter(start_after=reply.seq).
    """

    def __init__(self, start_after: int = 0):
        if not 0 <= start_after < RANGES["seq"][1]:
            raise ValueError(f"start_after={start_after} outside [0, {RANGES['seq'][1]})")
        self._last = start_after

    def next(self) -> int:
        if self._last >= RANGES["seq"][1]:
            raise OverflowError("sequence numbers exhausted: provision a new key")
        self._last += 1
        return self._last


_REPLY_RE = re.compile(r"^([1-5][0-9]{2}) (\{.*\})\r?\n?$", re.DOTALL)


def _int_list(obj: dict, name: str, n: int, lo: int, hi: int) -> tuple:
    v = obj[name]
    if (
        not isinstance(v, list)
        or len(v) != n
        or not all(isinstance(x, int) and not isinstance(x, bool) and lo <= x <= hi for x in v)
    ):
        raise ValueError(f"reply field {name} must be {n} integers in [{lo}, {hi}], got {v!r}")
    return tuple(v)


def _opt_age(obj: dict, name: str) -> int | None:
    v = obj[name]
    if v is None:
        return None
    if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= 0xFFFFFFFF:
        raise ValueError(f"reply field {name} must be null or a u32, got {v!r}")
    return v


def parse_reply(line: str) -> Reply:
    """Parses one reply line '<status> <json>'. Raises ValueError on anything malformed."""
    m = _REPLY_RE.match(line)
    if not m:
        raise ValueError(f"not a reply line: {line[:80]!r}")
    status = int(m.group(1))
    if status not in STATUS_REASONS:
        raise ValueError(f"unknown status {status}")
    try:
        obj = json.loads(m.group(2))
    except json.JSONDecodeError as e:
        raise ValueError(f"reply JSON invalid: {e}") from e
    ver = obj.get("ver") if isinstance(obj, dict) and next(iter(obj), None) == "ver" else None
    if ver is not None and (type(ver) is not int or ver != CONTROL_LINK_VERSION):
        # Checked before the layout: a peer of another version may have changed everything after it.
        raise ValueError(
            f"control-link version {obj['ver']!r} from the firmware, {CONTROL_LINK_VERSION} here: "
            "update the firmware or the ground station"
        )
    if not isinstance(obj, dict) or list(obj.keys()) != REPLY_FIELDS:
        raise ValueError(
            f"reply keys {list(obj) if isinstance(obj, dict) else obj!r} != {REPLY_FIELDS}"
        )
    if obj["err"] != STATUS_REASONS[status]:
        raise ValueError(f"reason {obj['err']!r} does not match status {status}")
    if obj["state"] not in STATES:
        raise ValueError(f"unknown state {obj['state']!r}")
    if not isinstance(obj["fw"], str):
        raise ValueError("fw must be a string")
    seq = obj["seq"]
    if not isinstance(seq, int) or isinstance(seq, bool) or not 0 <= seq <= 0xFFFFFFFF:
        raise ValueError(f"seq must be a u32, got {seq!r}")
    clamped = obj["clamped"]
    if not isinstance(clamped, int) or isinstance(clamped, bool) or not 0 <= clamped <= 15:
        raise ValueError(f"clamped must be a 4-bit mask, got {clamped!r}")
    return Reply(
        status=status,
        ver=obj["ver"],
        err=obj["err"],
        fw=obj["fw"],
        state=obj["state"],
        seq=seq,
        out_us=_int_list(obj, "out_us", 4, 0, 65535),
        clamped=clamped,
        att_mrad=_int_list(obj, "att_mrad", 3, -32768, 32767),
        att_age_ms=_opt_age(obj, "att_age_ms"),
        imu_raw=_int_list(obj, "imu_raw", 6, -32768, 32767),
        imu_age_ms=_opt_age(obj, "imu_age_ms"),
    )
