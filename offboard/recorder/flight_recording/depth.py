"""Decoders for the recorded depth (`/camera/depth/compressed`, rgbdquad.CompressedDepth).

The recorder stores the depth payload as the camera link carried it; the formats are the wire
contract's (protocol/encodings/README.md), decoded here with numpy so a recording needs nothing
but Python to read:

- ``rvl``: RVL (Wilson, ISS 2017). Values are coded in 3-bit groups, least significant first, bit 3
  of a nibble set while more groups follow; 8 nibbles per 32-bit little-endian word, the first
  nibble in the top bits; the last word zero-padded. The value stream repeats {zero-run length,
  non-zero run length, that many zig-zag deltas against the previous non-zero pixel}.
- ``zstd-delta``: one zstd frame of row-wise deltas (pixel minus its left neighbour, the first pixel
  minus 0, mod 2^16), uint16 little-endian.
- ``raw``: uint16 little-endian per pixel.

Every decoder returns a (height, width) uint16 array or raises ValueError naming what is wrong.
"""

from __future__ import annotations

import numpy as np

_NIBBLE_SHIFTS = np.arange(28, -1, -4, dtype=np.uint32)  # first nibble in the word's top bits


def _rvl_values(payload: bytes) -> np.ndarray:
    if len(payload) % 4:
        raise ValueError(f"rvl: {len(payload)} bytes is not a whole number of 32-bit words")
    words = np.frombuffer(payload, dtype="<u4")
    nibbles = ((words[:, None] >> _NIBBLE_SHIFTS) & 0xF).astype(np.uint8).ravel()
    ends = np.flatnonzero((nibbles & 8) == 0)
    if ends.size == 0:
        return np.zeros(0, dtype=np.int64)
    nibbles = nibbles[: ends[-1] + 1]
    starts = np.concatenate(([0], ends[:-1] + 1))
    lengths = ends - starts + 1
    if lengths.max() > 11:  # 11 groups of 3 bits hold any uint32; more is a damaged payload
        raise ValueError("rvl: a value longer than 32 bits")
    position = np.arange(nibbles.size) - np.repeat(starts, lengths)
    contrib = (nibbles & 7).astype(np.int64) << (3 * position)
    return np.add.reduceat(contrib, starts)


def rvl_decode(payload: bytes, width: int, height: int) -> np.ndarray:
    n = width * height
    values = _rvl_values(payload)
    out = np.zeros(n, dtype=np.uint16)
    runs = []  # (first pixel, count, first value index) of each non-zero run
    i = pixel = 0
    while pixel < n:
        if i + 2 > values.size:
            raise ValueError(f"rvl: truncated at pixel {pixel} of {n}")
        zeros, nonzeros = int(values[i]), int(values[i + 1])
        i += 2
        pixel += zeros
        if pixel + nonzeros > n or i + nonzeros > values.size:
            raise ValueError(f"rvl: a run passes the end of the image or payload at pixel {pixel}")
        if nonzeros:
            runs.append((pixel, nonzeros, i))
        i += nonzeros
        pixel += nonzeros
    if not runs:
        return out.reshape(height, width)
    coded = np.concatenate([values[v : v + c] for _, c, v in runs])
    deltas = (coded >> 1) ^ -(coded & 1)  # zig-zag
    pixels = np.cumsum(deltas)  # each value is the previous non-zero pixel plus its delta
    if pixels.min() <= 0 or pixels.max() > 0xFFFF:
        raise ValueError("rvl: a delta leaves the uint16 range")
    index = np.concatenate([np.arange(p, p + c) for p, c, _ in runs])
    out[index] = pixels.astype(np.uint16)
    return out.reshape(height, width)


def zstd_delta_decode(payload: bytes, width: int, height: int) -> np.ndarray:
    import zstandard

    try:
        raw = zstandard.ZstdDecompressor().decompress(payload)
    except zstandard.ZstdError as e:
        raise ValueError(f"zstd-delta: {e}") from e
    if len(raw) != width * height * 2:
        raise ValueError(f"zstd-delta: {len(raw)} bytes decoded, expected {width * height * 2}")
    deltas = np.frombuffer(raw, dtype="<u2").reshape(height, width)
    return np.cumsum(deltas, axis=1, dtype=np.uint16)  # mod 2^16, as encoded


def raw_decode(payload: bytes, width: int, height: int) -> np.ndarray:
    if len(payload) != width * height * 2:
        raise ValueError(f"raw: {len(payload)} bytes, expected {width * height * 2}")
    return np.frombuffer(payload, dtype="<u2").reshape(height, width).copy()


DECODERS = {"rvl": rvl_decode, "zstd-delta": zstd_delta_decode, "raw": raw_decode}


def decode(encoding: str, payload: bytes, width: int, height: int) -> np.ndarray:
    if encoding not in DECODERS:
        raise ValueError(f"unknown depth encoding {encoding!r} (known: {', '.join(DECODERS)})")
    return DECODERS[encoding](payload, width, height)
