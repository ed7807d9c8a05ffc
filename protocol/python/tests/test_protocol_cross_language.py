"""Cross-language round trips through build/bin/rgbd-protocol-tool (RGBD_BUILD_DIR overrides the
build dir): Python encodes -> C++ decodes, C++ encodes -> Python decodes, hostile vectors decode to
the same events in both."""

import json
import os
import random
import subprocess
from pathlib import Path

import pytest
from rgbd_protocol import Codec, StreamDecoder, event_view, normalize_events
from rgbd_protocol.tum_cameras import TUM_DEPTH_UNITS_PER_M

ROOT = Path(__file__).resolve().parents[3]
BUILD = Path(os.environ.get("RGBD_BUILD_DIR", ROOT / "build"))
TOOL = BUILD / "bin" / "rgbd-protocol-tool"
VECTORS = ROOT / "protocol" / "vectors"
CODEC = Codec()

pytestmark = pytest.mark.skipif(
    not BUILD.is_dir(), reason=f"build dir {BUILD} absent (build first or set RGBD_BUILD_DIR)"
)


def tool(*args, data: bytes = b"") -> subprocess.CompletedProcess:
    assert TOOL.exists(), f"{TOOL} missing although {BUILD} exists: build rgbd-protocol-tool"
    return subprocess.run([str(TOOL), *args], input=data, capture_output=True, timeout=120)


def cpp_decode(data: bytes, chunk: int = 0) -> tuple[list[dict], int]:
    r = tool("decode", *(["--chunk", str(chunk)] if chunk else []), data=data)
    assert r.returncode == 0, r.stderr.decode()
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert lines[-1]["event"] == "end"
    events = [{k: v for k, v in e.items() if k != "detail"} for e in lines[:-1]]
    return normalize_events(events), lines[-1]["buffered_bytes"]


def random_messages(seed: int, count: int) -> list[tuple[str, dict]]:
    """Seeded valid messages of every kind, with values spread over their ranges."""
    rng = random.Random(seed)

    def accel():
        if rng.random() < 0.3:
            return {"valid": False, "capture_timestamp_us": 0, "f_mps2": [0.0, 0.0, 0.0]}
        return {
            "valid": True,
            "capture_timestamp_us": rng.getrandbits(64),
            "f_mps2": [rng.uniform(-1000, 1000) for _ in range(3)],
        }

    def q():
        v = [rng.uniform(-1, 1) for _ in range(4)]
        n = sum(x * x for x in v) ** 0.5
        return [x / n for x in v]

    def pose():
        return {"t_m": [rng.uniform(-50, 50) for _ in range(3)], "q_xyzw": q()}

    def image(fmt, w, h):
        bpp = 3 if fmt == "RGB8" else 2
        return {
            "sequence": rng.getrandbits(32),
            "capture_timestamp_us": rng.getrandbits(64),
            "send_timestamp_us": rng.getrandbits(64),
            "width": w,
            "height": h,
            "pixel_format": fmt,
            "encoding": "RAW",
            "payload": rng.randbytes(w * h * bpp),
        }

    intr = {
        "fx_px": rng.uniform(1, 1000),
        "fy_px": rng.uniform(1, 1000),
        "cx_px": rng.uniform(-500, 500),
        "cy_px": rng.uniform(-500, 500),
        "distortion": [rng.uniform(-2, 2) for _ in range(5)],
    }
    makers = [
        lambda: (
            "Handshake",
            {
                "protocol_version": CODEC.spec.version,
                "schema_hash": CODEC.spec.schema_hash,
                "stream_kind": "DEPTH",
                "width": rng.randint(1, 4096),
                "height": rng.randint(1, 4096),
                "pixel_format": "DEPTH16",
                "encoding": rng.choice(["RAW", "DEPTH_RVL", "DEPTH_ZSTD_DELTA"]),
                "intrinsics": intr,
                "depth_scale_units_per_m": 1000.0,
                "device_id": "".join(chr(rng.randint(32, 126)) for _ in range(rng.randint(0, 255))),
                "sender_nonce": list(rng.randbytes(16)),
                "mac": list(rng.randbytes(8)),
            },
        ),
        lambda: (
            "HandshakeAck",
            {"accepted": rng.random() < 0.5, "reason": "because", "mac": list(rng.randbytes(8))},
        ),
        lambda: ("StreamChallenge", {"receiver_nonce": list(rng.randbytes(16))}),
        lambda: (
            "Frame",
            {
                "image": image(
                    rng.choice(["RGB8", "DEPTH16"]), rng.randint(1, 40), rng.randint(1, 30)
                ),
                "accel": accel(),
            },
        ),
        lambda: (
            "FrameRequest",
            {"credits": rng.randint(1, 8), "last_received_sequence": rng.getrandbits(32)},
        ),
        lambda: (
            "SlamHello",
            {
                "protocol_version": CODEC.spec.version,
                "schema_hash": rng.getrandbits(64),
                "peer_name": "slam-server",
                "session_id": rng.getrandbits(64),
                "resumed": rng.random() < 0.5,
                "session_frames": rng.getrandbits(32),
                "refusal": rng.choice(["", "slam-server busy: all 4 client slots in use"]),
            },
        ),
        lambda: (
            "RgbdFrame",
            {
                "pair_sequence": rng.getrandbits(32),
                "intrinsics": intr,
                "depth_scale_units_per_m": TUM_DEPTH_UNITS_PER_M,
                "attitude": rng.choice(
                    [
                        {"valid": True, "q_xyzw": q()},
                        {"valid": False, "q_xyzw": [0.0, 0.0, 0.0, 1.0]},
                    ]
                ),
                "rgb": image("RGB8", 8, 6),
                "depth": image("DEPTH16", 8, 6),
                "accel": accel(),
            },
        ),
        lambda: (
            "PoseUpdate",
            {
                "pair_sequence": rng.getrandbits(32),
                "timestamp_us": rng.getrandbits(64),
                "tracking_state": rng.choice(["INITIALIZING", "TRACKING", "LOST", "RELOCALIZED"]),
                "T_world_cam": pose(),
                "T_prev_cur": pose(),
                "is_keyframe": rng.random() < 0.5,
                "inlier_count": rng.getrandbits(32),
                "map_correction_count": rng.getrandbits(32),
            },
        ),
        lambda: (
            "PoseGraph",
            {
                "revision": rng.getrandbits(32),
                "timestamp_us": rng.getrandbits(64),
                "stage": rng.choice(["BEFORE_OPTIMISATION", "AFTER_OPTIMISATION"]),
                "nodes": [
                    {"node_id": i, "timestamp_us": rng.getrandbits(64), "T_world_node": pose()}
                    for i in range(rng.randint(0, 30))
                ],
                "edges": [
                    {
                        "from_id": rng.getrandbits(32),
                        "to_id": rng.getrandbits(32),
                        "kind": rng.choice(["ODOMETRY", "LOOP_CLOSURE"]),
                        "T_from_to": pose(),
                    }
                    for _ in range(rng.randint(0, 40))
                ],
            },
        ),
        lambda: (
            "FloorMap",
            {
                "revision": 1,
                "timestamp_us": rng.getrandbits(64),
                "resolution_m": rng.uniform(0.001, 1.0),
                "origin_x_m": rng.uniform(-100, 100),
                "origin_y_m": rng.uniform(-100, 100),
                "width_cells": 20,
                "height_cells": 10,
                "cell_format": rng.choice(["OCCUPANCY_U8", "POINT_COUNT_U8"]),
                "cells": rng.randbytes(200),
            },
        ),
    ]
    return [makers[i % len(makers)]() for i in range(count)]


def test_tool_help_is_truthful():
    r = tool("--help")
    assert r.returncode == 0
    text = r.stdout.decode()
    for command in ("encode", "decode", "schema-hash"):
        assert command in text
    assert tool("bogus").returncode == 2


def test_both_sides_speak_the_same_schema():
    out = tool("schema-hash").stdout.decode()
    assert f"0x{CODEC.spec.schema_hash:016x}" in out


@pytest.mark.parametrize("chunk", [0, 1, 4096])
def test_python_encodes_cpp_decodes(chunk):
    messages = random_messages(seed=11, count=45)
    data = b"".join(CODEC.encode(n, f) for n, f in messages)
    events, buffered = cpp_decode(data, chunk)
    assert buffered == 0
    assert events == [{"event": "message", "message": CODEC.to_view(n, f)} for n, f in messages]


def test_cpp_encodes_python_decodes():
    messages = random_messages(seed=12, count=45)
    lines = "\n".join(json.dumps(CODEC.to_view(n, f)) for n, f in messages) + "\n"
    r = tool("encode", data=lines.encode())
    assert r.returncode == 0, r.stderr.decode()
    assert r.stdout == b"".join(CODEC.encode(n, f) for n, f in messages)  # byte-identical
    dec = StreamDecoder(CODEC)
    dec.feed(r.stdout)
    got = [(e.name, e.fields) for e in dec.drain()]
    assert got == messages


def test_full_size_frames_cross_both_ways():
    rng = random.Random(3)
    frames = [
        (
            "Frame",
            {
                "image": {
                    "sequence": s,
                    "capture_timestamp_us": 10 + s,
                    "send_timestamp_us": 20 + s,
                    "width": 640,
                    "height": 480,
                    "pixel_format": fmt,
                    "encoding": "RAW",
                    "payload": rng.randbytes(640 * 480 * bpp),
                },
                "accel": {
                    "valid": fmt == "RGB8",
                    "capture_timestamp_us": 10 + s if fmt == "RGB8" else 0,
                    "f_mps2": [0.25, 9.75, -1.5] if fmt == "RGB8" else [0.0, 0.0, 0.0],
                },
            },
        )
        for s, (fmt, bpp) in enumerate([("RGB8", 3), ("DEPTH16", 2)])
    ]
    data = b"".join(CODEC.encode(n, f) for n, f in frames)
    events, _ = cpp_decode(data, 65536)
    assert events == [{"event": "message", "message": CODEC.to_view(n, f)} for n, f in frames]
    lines = "\n".join(json.dumps(CODEC.to_view(n, f)) for n, f in frames) + "\n"
    assert tool("encode", data=lines.encode()).stdout == data


def test_cpp_encoder_refuses_invalid_messages_like_python():
    bad = {"type": "FrameRequest", "fields": {"credits": 0, "last_received_sequence": 0}}
    r = tool("encode", data=(json.dumps(bad) + "\n").encode())
    assert r.returncode == 1 and b"credits" in r.stderr
    r = tool("encode", data=b"{not json\n")
    assert r.returncode == 1 and r.stderr


def test_every_golden_vector_gives_the_same_events_in_cpp_and_python():
    manifest = json.loads((VECTORS / "manifest.json").read_text())
    blob = b""
    expected = []
    for v in manifest["vectors"]:
        data = (VECTORS / v["file"]).read_bytes()
        events, buffered = cpp_decode(data, 3)
        assert events == v["expected"]["events"], v["name"]
        assert buffered == v["expected"]["buffered_bytes"], v["name"]
        dec = StreamDecoder(CODEC)
        dec.feed(data)
        py = normalize_events([event_view(CODEC, e) for e in dec.drain()])
        assert py == events, v["name"]
        if v["expected"]["buffered_bytes"] == 0:
            blob += data
            expected += v["expected"]["events"]
    # All complete vectors back to back: the decoders stay in step across every kind of fault.
    events, _ = cpp_decode(blob, 1000)
    dec = StreamDecoder(CODEC)
    dec.feed(blob)
    assert normalize_events([event_view(CODEC, e) for e in dec.drain()]) == events
    assert events == normalize_events(expected)


def mutated_bodies(seed: int, per_seed: int) -> list[tuple[int, bytes]]:
    """Seeded mutations (byte flips, truncation, insertion) of every corpus body, with its type."""
    spec = CODEC.spec
    ids = {m["name"]: m["id"] for m in spec.messages}
    target_to_type = {
        "handshake": "Handshake",
        "handshake_ack": "HandshakeAck",
        "frame": "Frame",
        "stream_challenge": "StreamChallenge",
        "frame_request": "FrameRequest",
        "slam_hello": "SlamHello",
        "rgbd_frame": "RgbdFrame",
        "pose_update": "PoseUpdate",
        "pose_graph": "PoseGraph",
        "floor_map": "FloorMap",
    }
    rng = random.Random(seed)
    out = []
    for target, name in target_to_type.items():
        for path in sorted((VECTORS / "corpus" / target).glob("*.bin")):
            body = path.read_bytes()
            for _ in range(per_seed):
                b = bytearray(body)
                op = rng.randrange(3)
                if op == 0 and b:
                    for _ in range(rng.randint(1, 3)):
                        b[rng.randrange(len(b))] = rng.randrange(256)
                elif op == 1 and b:
                    del b[rng.randrange(len(b)) :]
                else:
                    b[rng.randint(0, len(b)) : rng.randint(0, len(b))] = rng.randbytes(
                        rng.randint(1, 4)
                    )
                out.append((ids[name], bytes(b)))
    return out


def test_mutated_bodies_in_valid_envelopes_give_the_same_verdicts_in_cpp_and_python():
    # Valid CRCs around hostile bodies, so every body decoder is reached in both languages.
    cases = mutated_bodies(seed=99, per_seed=12)
    stream = b"".join(CODEC.wrap(type_id, body) for type_id, body in cases)
    cpp_events, buffered = cpp_decode(stream, 65536)
    dec = StreamDecoder(CODEC)
    dec.feed(stream)
    py_events = normalize_events([event_view(CODEC, e) for e in dec.drain()])
    assert buffered == 0 and dec.buffered_bytes == 0
    assert len(py_events) == len(cases)
    assert cpp_events == py_events
    verdicts = {e.get("error", "message") for e in py_events}
    # The mutations reach the structural and the value checks, not just one of them.
    assert {"message", "truncated_body", "invalid_value"} <= verdicts, verdicts
