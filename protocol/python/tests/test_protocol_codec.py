"""Python codec: golden vectors, round trips, encoder refusals and seeded hostile input."""

import json
import math
import random
import struct
import zlib
from pathlib import Path

import pytest
from rgbd_protocol import Codec, EncodeError, StreamDecoder, event_view, normalize_events

VECTORS = Path(__file__).resolve().parents[2] / "vectors"
CODEC = Codec()
MANIFEST = json.loads((VECTORS / "manifest.json").read_text())


def replay(data: bytes, chunk: int):
    dec = StreamDecoder(CODEC)
    events = []
    for i in range(0, len(data), chunk or max(len(data), 1)):
        dec.feed(data[i : i + (chunk or len(data))])
        events += dec.drain()
    return events, dec.buffered_bytes


@pytest.mark.parametrize("vector", MANIFEST["vectors"], ids=lambda v: v["name"])
@pytest.mark.parametrize("chunk", [0, 1, 5])
def test_golden_vector(vector, chunk):
    data = (VECTORS / vector["file"]).read_bytes()
    events, buffered = replay(data, chunk)
    got = normalize_events([event_view(CODEC, e) for e in events])
    assert got == vector["expected"]["events"]
    assert buffered == vector["expected"]["buffered_bytes"]
    if vector["reencodes_to_same_bytes"]:
        # Each message re-encodes in the envelope version it came in (an older peer's included).
        assert b"".join(CODEC.encode(e.name, e.fields, version=e.version) for e in events) == data
    for e in events:
        if e.name in ("Handshake", "SlamHello"):
            reason = CODEC.incompatibility(e.fields)
            assert (vector.get("refused", "") in reason) if "refused" in vector else reason == ""


def test_manifest_is_for_this_schema():
    assert MANIFEST["schema_hash"] == f"0x{CODEC.spec.schema_hash:016x}"


def test_envelope_layout_is_little_endian():
    data = CODEC.encode("FrameRequest", {"credits": 3, "last_received_sequence": 0x01020304})
    assert data[:4] == b"RGBQ" and data[4] == CODEC.spec.version and data[5] == 4
    assert struct.unpack_from("<HI", data, 6) == (0, 6)
    assert struct.unpack_from("<I", data, 12)[0] == zlib.crc32(data[:12])
    assert data[16:22] == bytes([3, 0, 4, 3, 2, 1])
    assert struct.unpack_from("<I", data, 22)[0] == zlib.crc32(data[16:22])


def test_full_size_kinect_frames_round_trip():
    rng = random.Random(7)
    for fmt, bpp in (("RGB8", 3), ("DEPTH16", 2)):
        payload = rng.randbytes(640 * 480 * bpp)
        fields = {
            "image": {
                "sequence": 1,
                "capture_timestamp_us": 2,
                "send_timestamp_us": 3,
                "width": 640,
                "height": 480,
                "pixel_format": fmt,
                "encoding": "RAW",
                "payload": payload,
            },
            # The RGB stream carries the accelerometer sample, the depth stream none.
            "accel": {
                "valid": fmt == "RGB8",
                "capture_timestamp_us": 2 if fmt == "RGB8" else 0,
                "f_mps2": [0.5, 9.5, -1.25] if fmt == "RGB8" else [0.0, 0.0, 0.0],
            },
        }
        dec = StreamDecoder(CODEC)
        dec.feed(CODEC.encode("Frame", fields))
        (event,) = dec.drain()
        assert event.kind == "message" and event.fields == fields


@pytest.mark.parametrize(
    "name,fields,field",
    [
        ("FrameRequest", {"credits": 0, "last_received_sequence": 0}, "credits"),
        ("FrameRequest", {"credits": 9, "last_received_sequence": 0}, "credits"),
        ("FrameRequest", {"credits": 1}, "missing"),
        ("FrameRequest", {"credits": 1.5, "last_received_sequence": 0}, "credits"),
        ("HandshakeAck", {"accepted": True, "reason": "x" * 256, "mac": [0] * 8}, "reason"),
        ("HandshakeAck", {"accepted": True, "reason": "caf\u00e9", "mac": [0] * 8}, "reason"),
        ("HandshakeAck", {"accepted": 1, "reason": "", "mac": [0] * 8}, "accepted"),
        ("HandshakeAck", {"accepted": True, "reason": "", "mac": [0] * 7}, "mac"),
        ("StreamChallenge", {"receiver_nonce": [256] + [0] * 15}, "receiver_nonce"),
        (
            "FloorMap",
            {
                "revision": 0,
                "timestamp_us": 0,
                "resolution_m": math.nan,
                "origin_x_m": 0.0,
                "origin_y_m": 0.0,
                "width_cells": 1,
                "height_cells": 1,
                "cell_format": "OCCUPANCY_U8",
                "cells": b"\0",
            },
            "resolution_m",
        ),
        (
            "FloorMap",
            {
                "revision": 0,
                "timestamp_us": 0,
                "resolution_m": 0.05,
                "origin_x_m": 0.0,
                "origin_y_m": 0.0,
                "width_cells": 2,
                "height_cells": 1,
                "cell_format": "OCCUPANCY_U8",
                "cells": b"\0",
            },
            "cells",
        ),
        (
            "Frame",
            {
                "image": {
                    "sequence": 0,
                    "capture_timestamp_us": 0,
                    "send_timestamp_us": 0,
                    "width": 2,
                    "height": 2,
                    "pixel_format": "RGB8",
                    "encoding": "NOPE",
                    "payload": b"",
                }
            },
            "encoding",
        ),
    ],
)
def test_encoder_refuses_messages_that_break_the_spec(name, fields, field):
    with pytest.raises(EncodeError, match=field):
        CODEC.encode(name, fields)


def test_seeded_random_bytes_never_raise_and_always_progress():
    rng = random.Random(2024)
    seeds = [(VECTORS / v["file"]).read_bytes() for v in MANIFEST["vectors"]]
    for trial in range(300):
        data = bytearray(rng.choice(seeds) + rng.choice(seeds))
        for _ in range(rng.randint(1, 6)):
            if data:
                data[rng.randrange(len(data))] = rng.randrange(256)
        dec = StreamDecoder(CODEC)
        dec.feed(bytes(data))
        for _ in range(len(data) + 2):
            before = dec.buffered_bytes
            e = dec.next()
            if e.kind == "need_more":
                break
            assert dec.buffered_bytes < before, trial
        else:
            pytest.fail("decoder did not settle")


def test_decoder_cap_refuses_bodies_above_it_before_they_arrive():
    fields = {
        "image": {
            "sequence": 0,
            "capture_timestamp_us": 0,
            "send_timestamp_us": 0,
            "width": 8,
            "height": 8,
            "pixel_format": "RGB8",
            "encoding": "RAW",
            "payload": bytes(192),
        }
    }
    data = CODEC.encode("Frame", fields)
    dec = StreamDecoder(CODEC, max_body_bytes=64)
    dec.feed(data[:16])  # the header alone is enough to refuse
    (event,) = dec.drain()
    assert event.error == "body_too_large"


def test_schema_mismatch_reason_names_both_hashes():
    ours = CODEC.spec.version
    reason = CODEC.incompatibility({"protocol_version": ours, "schema_hash": 1})
    assert "0x0000000000000001" in reason and f"{CODEC.spec.schema_hash:016x}" in reason
    assert "version" in CODEC.incompatibility({"protocol_version": ours + 1, "schema_hash": 1})
    assert (
        CODEC.incompatibility({"protocol_version": ours, "schema_hash": CODEC.spec.schema_hash})
        == ""
    )


def test_every_decoded_version_is_accepted_with_its_own_schema_hash():
    """A peer of an older version (a craft running the previous streamer) is accepted with that
    version's hash, and refused with any other."""
    old = CODEC.spec.oldest_decoded_version
    assert old < CODEC.spec.version
    old_hash = CODEC.spec.at_version(old).schema_hash
    assert CODEC.incompatibility({"protocol_version": old, "schema_hash": old_hash}) == ""
    assert "schema hash" in CODEC.incompatibility(
        {"protocol_version": old, "schema_hash": CODEC.spec.schema_hash}
    )


def test_projection_to_version_1_reproduces_its_published_schema_hash():
    # 0x77ddddf95a1ffc23: the schema hash every version-1 build carries (docs/protocol.md of
    # that version); the projection must reproduce it or version-1 streamers are refused.
    assert CODEC.spec.at_version(1).schema_hash == 0x77DDDDF95A1FFC23
    assert CODEC.spec.at_version(1).message("Frame")["max_body_bytes"] == 1048606


def test_old_version_frame_decodes_with_accel_not_valid_and_reencodes_in_its_version():
    fields = {
        "image": {
            "sequence": 3,
            "capture_timestamp_us": 10,
            "send_timestamp_us": 11,
            "width": 1,
            "height": 1,
            "pixel_format": "RGB8",
            "encoding": "RAW",
            "payload": b"abc",
        }
    }
    old = CODEC.encode("Frame", fields, version=1)
    assert old[4] == 1 and len(old) == len(CODEC.encode("Frame", fields)) - 33
    dec = StreamDecoder(CODEC)
    dec.feed(old)
    (event,) = dec.drain()
    assert event.kind == "message" and event.version == 1
    assert event.fields["accel"]["valid"] is False
    assert CODEC.encode("Frame", event.fields, version=event.version) == old
