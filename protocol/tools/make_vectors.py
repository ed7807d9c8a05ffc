#!/usr/bin/env python3
"""Writes the golden test vectors: protocol/vectors/*.bin, protocol/vectors/manifest.json and the
libFuzzer seed corpora protocol/vectors/corpus/<target>/.

Each vector is a byte stream plus the events a StreamDecoder must report for it, written down here
by hand (message views from the input fields, error names with the byte counts they drop), not
taken from a decoder. The Python decoder is checked against them before anything is written; the
C++ and Python test suites replay them. `--check` regenerates in memory and exits 1 when the
committed files differ (pytest runs it, so vectors never drift from the spec).

Usage: make_vectors.py [--check]
"""

from __future__ import annotations

import argparse
import json
import math
import struct
import sys
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from rgbd_protocol.codec import (  # noqa: E402
    Codec,
    EncodeError,
    StreamDecoder,
    event_view,
    normalize_events,
)
from rgbd_protocol.stream_auth import ack_tag, handshake_tag  # noqa: E402
from rgbd_protocol.tum_cameras import TUM_DEPTH_UNITS_PER_M, TUM_FR1  # noqa: E402

VECTORS = ROOT / "vectors"
# Fuzz targets and the message whose bodies seed them (scripts/fuzz.sh: corpus/<target>).
BODY_FUZZERS = {
    "Handshake": "handshake",
    "HandshakeAck": "handshake_ack",
    "Frame": "frame",
    "FrameRequest": "frame_request",
    "StreamChallenge": "stream_challenge",
    "SlamHello": "slam_hello",
    "RgbdFrame": "rgbd_frame",
    "PoseUpdate": "pose_update",
    "PoseGraph": "pose_graph",
    "FloorMap": "floor_map",
}

# TUM fr1 colour intrinsics and its depth scale (protocol/camera/tum_cameras.json).
FR1 = TUM_FR1.intrinsics()


def unit_q(x, y, z, w):
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return [x / n, y / n, z / n, w / n]


IDENTITY = {"t_m": [0.0, 0.0, 0.0], "q_xyzw": [0.0, 0.0, 0.0, 1.0]}


# Stream authentication of the vectors (manifest "stream_auth"): the SipHash paper's key
# 00 01 .. 0f and two fixed nonces, so every implementation can recompute each mac.
AUTH_KEY = bytes(range(16))
RECEIVER_NONCE = bytes(range(0x10, 0x20))
SENDER_NONCE = bytes(range(0x20, 0x30))


def handshake(kind="DEPTH", **over):
    """A Handshake signed under AUTH_KEY answering RECEIVER_NONCE (unless `mac` is given)."""
    f = {
        "protocol_version": Codec().spec.version,
        "schema_hash": Codec().spec.schema_hash,
        "stream_kind": kind,
        "width": 640,
        "height": 480,
        "pixel_format": "DEPTH16" if kind == "DEPTH" else "RGB8",
        "encoding": "RAW",
        "intrinsics": FR1,
        "depth_scale_units_per_m": TUM_DEPTH_UNITS_PER_M if kind == "DEPTH" else 0.0,
        "device_id": "fakenect:tum-fr1-xyz",
        "sender_nonce": list(SENDER_NONCE),
        "mac": [0] * 8,
    }
    f.update(over)
    if "mac" not in over:
        try:
            f["mac"] = handshake_tag(Codec(), AUTH_KEY, RECEIVER_NONCE, f)
        except EncodeError:
            pass  # an invalid handshake (hostile vectors) is never authenticated: mac stays zero
    return f


def ack(accepted=True, reason=""):
    """A HandshakeAck signed under AUTH_KEY for RECEIVER_NONCE / SENDER_NONCE."""
    f = {"accepted": accepted, "reason": reason, "mac": [0] * 8}
    f["mac"] = ack_tag(Codec(), AUTH_KEY, RECEIVER_NONCE, SENDER_NONCE, f)
    return f


def image(fmt="RGB8", w=4, h=3, seq=0, encoding="RAW", payload=None):
    bpp = 3 if fmt == "RGB8" else 2
    if payload is None:
        if fmt == "RGB8":
            payload = bytes((i * 37 + seq) & 0xFF for i in range(w * h * bpp))
        else:  # depth in TUM units (5000/m): 1.0 m .. with one invalid (0) pixel
            vals = [0] + [int(TUM_DEPTH_UNITS_PER_M) + 17 * i for i in range(w * h - 1)]
            payload = b"".join(struct.pack("<H", v) for v in vals)
    return {
        "sequence": seq,
        "capture_timestamp_us": 1305031102175304 + 33333 * seq,
        "send_timestamp_us": 52_000_000 + 33_400 * seq,
        "width": w,
        "height": h,
        "pixel_format": fmt,
        "encoding": encoding,
        "payload": payload,
    }


def pose_update(**over):
    f = {
        "pair_sequence": 12,
        "timestamp_us": 1305031102175304,
        "tracking_state": "TRACKING",
        "T_world_cam": {
            "t_m": [1.3405, 0.6266, 1.6575],
            "q_xyzw": unit_q(0.6574, 0.6126, -0.2949, -0.3248),
        },
        "T_prev_cur": {
            "t_m": [0.0021, -0.0005, 0.0013],
            "q_xyzw": unit_q(0.001, -0.002, 0.0005, 1.0),
        },
        "is_keyframe": True,
        "inlier_count": 312,
        "map_correction_count": 2,
    }
    f.update(over)
    return f


def pose_graph(stage="BEFORE_OPTIMISATION"):
    shift = 0.0 if stage == "BEFORE_OPTIMISATION" else -0.01
    nodes = [
        {
            "node_id": i,
            "timestamp_us": 1305031102175304 + 500_000 * i,
            "T_world_node": {
                "t_m": [0.1 * i + shift * i, 0.02 * i, 1.5],
                "q_xyzw": unit_q(0.0, 0.0, 0.05 * i, 1.0),
            },
        }
        for i in range(3)
    ]
    edges = [
        {
            "from_id": 0,
            "to_id": 1,
            "kind": "ODOMETRY",
            "T_from_to": {"t_m": [0.1, 0.02, 0.0], "q_xyzw": unit_q(0, 0, 0.05, 1)},
        },
        {
            "from_id": 1,
            "to_id": 2,
            "kind": "ODOMETRY",
            "T_from_to": {"t_m": [0.1, 0.02, 0.0], "q_xyzw": unit_q(0, 0, 0.05, 1)},
        },
        {
            "from_id": 0,
            "to_id": 2,
            "kind": "LOOP_CLOSURE",
            "T_from_to": {"t_m": [0.19, 0.04, 0.0], "q_xyzw": unit_q(0, 0, 0.1, 1)},
        },
    ]
    return {
        "revision": 4,
        "timestamp_us": 1305031103175304,
        "stage": stage,
        "nodes": nodes,
        "edges": edges,
    }


def floor_map():
    cells = bytes([255, 255, 0, 0, 255, 0, 0, 100, 0, 0, 100, 100])
    return {
        "revision": 2,
        "timestamp_us": 1305031103175304,
        "resolution_m": 0.05,
        "origin_x_m": -0.1,
        "origin_y_m": -0.05,
        "width_cells": 4,
        "height_cells": 3,
        "cell_format": "OCCUPANCY_U8",
        "cells": cells,
    }


# R_ned_cam of a level craft heading north with the Kinect looking forward, unmounted (camera z =
# north, x = east, y = down): exactly (0.5, 0.5, 0.5, 0.5).
LEVEL_NORTH_ATTITUDE = {"valid": True, "q_xyzw": [0.5, 0.5, 0.5, 0.5]}
NO_ATTITUDE = {"valid": False, "q_xyzw": [0.0, 0.0, 0.0, 1.0]}


# A level Kinect at rest as libfreenect reports it (x left, y up, z forward): +1 g on y, exactly
# 819 counts * 9.80665 / 819, with a little tilt on x and z (counts 12 and -40).
KINECT_LEVEL_ACCEL = {
    "valid": True,
    "capture_timestamp_us": 1305031102175304,
    "f_mps2": [12 * 9.80665 / 819, 9.80665, -40 * 9.80665 / 819],
}
NO_ACCEL = {"valid": False, "capture_timestamp_us": 0, "f_mps2": [0.0, 0.0, 0.0]}


def rgbd_frame(attitude=None, accel=None):
    return {
        "pair_sequence": 12,
        "intrinsics": FR1,
        "depth_scale_units_per_m": TUM_DEPTH_UNITS_PER_M,
        "attitude": LEVEL_NORTH_ATTITUDE if attitude is None else attitude,
        "rgb": image("RGB8", 2, 2, 12),
        "depth": image("DEPTH16", 2, 2, 12),
        "accel": KINECT_LEVEL_ACCEL if accel is None else accel,
    }


class Builder:
    def __init__(self):
        self.codec = Codec()
        self.vectors: list[dict] = []
        self.files: dict[str, bytes] = {}
        self.bodies: dict[str, dict[str, bytes]] = {t: {} for t in BODY_FUZZERS.values()}
        self.bodies["stream"] = {}

    # -- pieces
    def msg(self, name, fields):
        return self.codec.encode(name, fields)

    def expect_msg(self, name, fields, version=None):
        """The decoded view of `fields` sent as `version` (default: ours): fields that version
        lacks, or that the caller left out, decode as their defaults."""
        present = {f["name"] for f in self.codec.message_at(name, version)["fields"]}
        full = {
            f["name"]: fields[f["name"]]
            if f["name"] in fields and f["name"] in present
            else self.codec.default_value(f)
            for f in self.codec.spec.message(name)["fields"]
        }
        return {"event": "message", "message": self.codec.to_view(name, full)}

    @staticmethod
    def expect_err(code, discarded):
        return {"event": "error", "error": code, "bytes_discarded": discarded}

    def forged(self, name, body, **wrap):
        type_id = self.codec.spec.message(name)["id"]
        return self.codec.wrap(type_id, body, **wrap)

    # -- registration
    def add(
        self,
        name,
        description,
        data,
        events,
        buffered=0,
        refused=None,
        reencodes=False,
        body_of=None,
    ):
        self.files[f"{name}.bin"] = data
        v = {
            "name": name,
            "file": f"{name}.bin",
            "description": description,
            "expected": {"events": events, "buffered_bytes": buffered},
            "reencodes_to_same_bytes": reencodes,
        }
        if refused is not None:
            v["refused"] = refused
        self.vectors.append(v)
        self.bodies["stream"][name] = data
        if body_of is not None:
            msg_name, body = body_of
            self.bodies[BODY_FUZZERS[msg_name]][name] = body

    def valid(self, name, description, msg_name, fields, refused=None, version=None):
        """A valid message; `version` writes it as that older version (as a peer that speaks it
        does): it decodes to `fields` with what that version lacks at its defaults."""
        data = self.codec.encode(msg_name, fields, version=version)
        self.add(
            name,
            description,
            data,
            [self.expect_msg(msg_name, fields, version)],
            refused=refused,
            reencodes=True,
            # An older version's body seeds the body fuzzer only where it is the current layout.
            body_of=(msg_name, data[16:-4])
            if data[16:-4] == self.codec.encode_body(msg_name, fields)
            else None,
        )
        return data

    def hostile_body(self, name, description, msg_name, body, code):
        data = self.forged(msg_name, body)
        self.add(
            name, description, data, [self.expect_err(code, len(data))], body_of=(msg_name, body)
        )

    # -- the set
    def build(self):
        c = self.codec
        self.valid(
            "handshake_rgb",
            "RGB stream handshake, 640x480 RGB8 RAW, TUM fr1 intrinsics",
            "Handshake",
            handshake("RGB"),
        )
        self.valid(
            "handshake_depth",
            "depth stream handshake, DEPTH16 RAW, 5000 units/m (TUM)",
            "Handshake",
            handshake("DEPTH"),
        )
        self.valid(
            "handshake_depth_rvl",
            "depth handshake announcing the reserved DEPTH_RVL "
            "encoding (compressed encodings need no version change)",
            "Handshake",
            handshake("DEPTH", encoding="DEPTH_RVL"),
        )
        self.valid("handshake_ack_accepted", "receiver accepts", "HandshakeAck", ack())
        self.valid(
            "handshake_ack_refused",
            "receiver refuses with a reason",
            "HandshakeAck",
            ack(False, "schema hash mismatch: peer 0x0000000000000001"),
        )
        # Sent before the receiver knows the streamer's version: in the oldest one still decoded.
        self.valid(
            "stream_challenge",
            "receiver's challenge (first message of a stream connection), in the oldest "
            "decoded version",
            "StreamChallenge",
            {"receiver_nonce": list(RECEIVER_NONCE)},
            version=c.spec.oldest_decoded_version,
        )
        # Decode fine, but their mac must not verify (stream_auth "forged").
        self.valid(
            "handshake_bad_mac",
            "RGB handshake whose mac has one bit flipped",
            "Handshake",
            handshake(
                "RGB", mac=[b ^ (1 if i == 0 else 0) for i, b in enumerate(handshake("RGB")["mac"])]
            ),
        )
        self.valid(
            "handshake_unsigned",
            "RGB handshake from a streamer without the key (mac zero)",
            "Handshake",
            handshake("RGB", mac=[0] * 8),
        )
        self.valid("frame_rgb_raw", "4x3 RGB8 RAW frame", "Frame", {"image": image("RGB8")})
        self.valid(
            "frame_rgb_accel",
            "4x3 RGB8 RAW frame with the Kinect's accelerometer sample (level, at rest)",
            "Frame",
            {"image": image("RGB8"), "accel": KINECT_LEVEL_ACCEL},
        )
        # Version 1 peers (a craft running the previous streamer): still decoded.
        old = c.spec.oldest_decoded_version
        self.valid(
            "frame_rgb_raw_v1",
            f"4x3 RGB8 RAW frame of protocol version {old} (no accel field)",
            "Frame",
            {"image": image("RGB8")},
            version=old,
        )
        self.valid(
            "handshake_rgb_v1",
            f"RGB handshake of a version {old} streamer with that version's schema hash",
            "Handshake",
            handshake("RGB", protocol_version=old, schema_hash=c.spec.at_version(old).schema_hash),
            version=old,
        )
        self.valid(
            "handshake_v1_with_v2_hash",
            f"handshake claiming version {old} with the current schema hash",
            "Handshake",
            handshake("RGB", protocol_version=old),
            refused="schema hash mismatch",
        )
        self.valid(
            "frame_depth_raw",
            "4x3 DEPTH16 RAW frame (one invalid 0 pixel)",
            "Frame",
            {"image": image("DEPTH16", seq=5)},
        )
        self.valid(
            "frame_depth_rvl",
            "DEPTH_RVL frame: payload opaque to the framing layer",
            "Frame",
            {"image": image("DEPTH16", 640, 480, 9, "DEPTH_RVL", bytes(range(256)) * 3)},
        )
        self.valid(
            "frame_rgb_jpeg",
            "RGB_JPEG frame: opaque payload",
            "Frame",
            {
                "image": image(
                    "RGB8", 640, 480, 9, "RGB_JPEG", b"\xff\xd8\xff\xe0" + bytes(60) + b"\xff\xd9"
                )
            },
        )
        self.valid(
            "frame_request",
            "receiver grants 2 credits, holds frame 41",
            "FrameRequest",
            {"credits": 2, "last_received_sequence": 41},
        )
        self.valid(
            "frame_request_first",
            "first request, nothing received yet",
            "FrameRequest",
            {"credits": 1, "last_received_sequence": 0xFFFFFFFF},
        )
        self.valid(
            "slam_hello",
            "SLAM link hello (client, new flight)",
            "SlamHello",
            {
                "protocol_version": c.spec.version,
                "schema_hash": c.spec.schema_hash,
                "peer_name": "quad-control",
                "session_id": 0x1F2E3D4C5B6A7988,
                "resumed": False,
                "session_frames": 0,
                "refusal": "",
            },
        )
        self.valid(
            "slam_hello_resumed",
            "SLAM link hello (server): the session's map continues",
            "SlamHello",
            {
                "protocol_version": c.spec.version,
                "schema_hash": c.spec.schema_hash,
                "peer_name": "slam-server",
                "session_id": 0x1F2E3D4C5B6A7988,
                "resumed": True,
                "session_frames": 205,
                "refusal": "",
            },
        )
        self.valid(
            "slam_hello_refused",
            "SLAM link hello (server): connection refused",
            "SlamHello",
            {
                "protocol_version": c.spec.version,
                "schema_hash": c.spec.schema_hash,
                "peer_name": "slam-server",
                "session_id": 0,
                "resumed": False,
                "session_frames": 0,
                "refusal": "slam-server busy: all 4 client slots in use",
            },
        )
        self.valid(
            "rgbd_frame",
            "2x2 RGB-D pair for the SLAM server, with the camera's IMU attitude",
            "RgbdFrame",
            rgbd_frame(),
        )
        self.valid(
            "rgbd_frame_no_attitude",
            "2x2 RGB-D pair without an attitude or accelerometer sample",
            "RgbdFrame",
            rgbd_frame(NO_ATTITUDE, NO_ACCEL),
        )
        self.valid(
            "rgbd_frame_v1",
            f"2x2 RGB-D pair of protocol version {old} (no accel field)",
            "RgbdFrame",
            rgbd_frame(),
            version=old,
        )
        self.valid(
            "pose_update", "tracking pose with egomotion, keyframe", "PoseUpdate", pose_update()
        )
        self.valid(
            "pose_update_lost",
            "tracking lost: identity poses, no inliers",
            "PoseUpdate",
            pose_update(
                tracking_state="LOST",
                T_world_cam=IDENTITY,
                T_prev_cur=IDENTITY,
                is_keyframe=False,
                inlier_count=0,
                map_correction_count=0,
            ),
        )
        self.valid(
            "pose_graph_before",
            "3 nodes, 2 odometry edges + 1 loop closure, before optimisation",
            "PoseGraph",
            pose_graph("BEFORE_OPTIMISATION"),
        )
        self.valid(
            "pose_graph_after",
            "the same graph after optimisation",
            "PoseGraph",
            pose_graph("AFTER_OPTIMISATION"),
        )
        self.valid(
            "pose_graph_empty",
            "empty graph",
            "PoseGraph",
            {
                "revision": 0,
                "timestamp_us": 0,
                "stage": "BEFORE_OPTIMISATION",
                "nodes": [],
                "edges": [],
            },
        )
        self.valid("floor_map", "4x3 occupancy map at 5 cm/cell", "FloorMap", floor_map())

        # A whole stream session: challenge, handshake, ack, request, three frames.
        session = [
            ("StreamChallenge", {"receiver_nonce": list(RECEIVER_NONCE)}),
            ("Handshake", handshake("RGB")),
            ("HandshakeAck", ack()),
            ("FrameRequest", {"credits": 3, "last_received_sequence": 0xFFFFFFFF}),
        ]
        session += [("Frame", {"image": image("RGB8", seq=s)}) for s in (0, 1, 3)]
        data = b"".join(self.msg(n, f) for n, f in session)
        self.add(
            "session_rgb",
            "challenge, handshake, ack, request, 3 frames back to back",
            data,
            [self.expect_msg(n, f) for n, f in session],
            reencodes=True,
        )

        # Peers that must be refused although their messages decode.
        self.valid(
            "handshake_wrong_schema_hash",
            "handshake from a build with another spec",
            "Handshake",
            handshake("RGB", schema_hash=c.spec.schema_hash ^ 0xDEADBEEF),
            refused="schema hash mismatch",
        )
        self.valid(
            "handshake_wrong_protocol_version_field",
            f"handshake claiming version {c.spec.version + 1}",
            "Handshake",
            handshake("RGB", protocol_version=c.spec.version + 1),
            refused="protocol version mismatch",
        )
        self.valid(
            "slam_hello_wrong_schema_hash",
            "SLAM hello from another spec",
            "SlamHello",
            {
                "protocol_version": c.spec.version,
                "schema_hash": 1,
                "peer_name": "old-build",
                "session_id": 0,
                "resumed": False,
                "session_frames": 0,
                "refusal": "",
            },
            refused="schema hash mismatch",
        )

        # Truncation.
        frame = self.msg("Frame", {"image": image("RGB8")})
        self.add("truncated_header", "10 bytes of a header", frame[:10], [], buffered=10)
        self.add(
            "truncated_body",
            "frame missing its last 5 bytes",
            frame[:-5],
            [],
            buffered=len(frame) - 5,
        )
        req = self.msg("FrameRequest", {"credits": 1, "last_received_sequence": 3})
        self.hostile_body(
            "body_shorter_than_fields",
            "FrameRequest body of 5 bytes",
            "FrameRequest",
            req[16:21],
            "truncated_body",
        )
        ack_body = c.encode_body("HandshakeAck", dict(ack(), reason="ok"))
        self.hostile_body(
            "body_trailing_bytes",
            "HandshakeAck body with one extra byte",
            "HandshakeAck",
            ack_body + b"\x00",
            "trailing_bytes",
        )

        # CRC errors.
        bad = bytearray(frame)
        bad[-1] ^= 0x01
        self.add(
            "bad_body_crc",
            "frame with a flipped CRC bit",
            bytes(bad),
            [self.expect_err("bad_body_crc", len(frame))],
        )
        bad = bytearray(frame)
        bad[30] ^= 0x10
        self.add(
            "bad_body_crc_then_valid",
            "corrupt payload byte, then a good request",
            bytes(bad) + req,
            [
                self.expect_err("bad_body_crc", len(frame)),
                self.expect_msg("FrameRequest", {"credits": 1, "last_received_sequence": 3}),
            ],
        )
        bad = bytearray(frame)
        bad[10] ^= 0x40  # body_length + 4 MiB
        self.add(
            "bad_header_crc",
            "corrupt body_length caught by the header CRC, then a request",
            bytes(bad) + req,
            [
                self.expect_err("bad_header_crc", len(frame)),
                self.expect_msg("FrameRequest", {"credits": 1, "last_received_sequence": 3}),
            ],
        )

        # Header fields.
        body = req[16:-4]
        data = self.forged("FrameRequest", body, version=c.spec.version + 1)
        self.add(
            "wrong_version",
            f"envelope version {c.spec.version + 1} (valid CRCs)",
            data,
            [self.expect_err("unsupported_version", len(data))],
        )
        data = c.wrap(99, body)
        self.add(
            "unknown_message_type",
            "type id 99",
            data,
            [self.expect_err("unknown_message_type", len(data))],
        )
        data = self.forged("FrameRequest", body, reserved=1)
        self.add(
            "reserved_nonzero",
            "reserved header bits set",
            data,
            [self.expect_err("reserved_nonzero", len(data))],
        )
        header = c.spec.magic + struct.pack("<BBHI", 1, 3, 0, 0xFFFFFFF0)
        data = header + struct.pack("<I", zlib.crc32(header))
        self.add(
            "oversized_body_length",
            "Frame header claiming a 4 GiB body (valid header CRC): refused from the header alone",
            data,
            [self.expect_err("body_too_large", len(data))],
        )
        header = c.spec.magic + struct.pack("<BBHI", 1, 4, 0, 7)
        data = header + struct.pack("<I", zlib.crc32(header)) + bytes(7) + b"\0\0\0\0"
        self.add(
            "body_above_type_max",
            "FrameRequest with a 7-byte body (max 6)",
            data,
            [self.expect_err("body_too_large", len(data))],
        )

        # Length prefixes above their limits (checked before allocating).
        fb = c.encode_body("Frame", {"image": image("RGB8")})
        self.hostile_body(
            "oversized_payload_length",
            "payload_length 2 MiB in a small body",
            "Frame",
            fb[:26] + struct.pack("<I", 2 << 20) + fb[30:],
            "length_too_large",
        )
        hb = c.encode_body("Handshake", handshake("RGB", device_id="x"))
        self.hostile_body(
            "oversized_string_length",
            "device_id length prefix 300 (max 255), 10 bytes present",
            "Handshake",
            hb[:-27] + struct.pack("<H", 300) + b"x" * 10,
            "length_too_large",
        )
        gb = c.encode_body("PoseGraph", pose_graph())
        self.hostile_body(
            "oversized_array_count",
            "PoseGraph nodes count 0xFFFFFFFF",
            "PoseGraph",
            gb[:13] + b"\xff\xff\xff\xff" + gb[17:],
            "length_too_large",
        )
        self.hostile_body(
            "array_count_beyond_body",
            "PoseGraph nodes count 16384, 3 present",
            "PoseGraph",
            gb[:13] + struct.pack("<I", 16384) + gb[17:],
            "truncated_body",
        )

        # Values the spec forbids (structurally sound bodies).
        def raw(name, fields):
            return c.encode_body(name, fields, validate=False)

        invalid = [
            (
                "invalid_pixel_format",
                "pixel_format 7",
                "Frame",
                raw("Frame", {"image": dict(image("RGB8"), pixel_format=7)}),
            ),
            (
                "invalid_encoding_code",
                "encoding 200 (unregistered)",
                "Frame",
                raw("Frame", {"image": dict(image("RGB8"), encoding=200)}),
            ),
            (
                "raw_payload_size_mismatch",
                "RAW 4x3 RGB8 with 35 bytes",
                "Frame",
                raw("Frame", {"image": dict(image("RGB8"), payload=bytes(35))}),
            ),
            (
                "encoding_pixel_format_mismatch",
                "DEPTH16 with RGB_JPEG",
                "Frame",
                raw("Frame", {"image": image("DEPTH16", encoding="RGB_JPEG", payload=b"x")}),
            ),
            (
                "zero_width",
                "width 0",
                "Frame",
                raw("Frame", {"image": dict(image("RGB8", 0, 3), payload=b"")}),
            ),
            (
                "credits_zero",
                "FrameRequest credits 0",
                "FrameRequest",
                raw("FrameRequest", {"credits": 0, "last_received_sequence": 1}),
            ),
            (
                "credits_above_max",
                "FrameRequest credits 9 (max 8)",
                "FrameRequest",
                raw("FrameRequest", {"credits": 9, "last_received_sequence": 1}),
            ),
            (
                "nan_intrinsics",
                "fx_px NaN",
                "Handshake",
                raw("Handshake", handshake("RGB", intrinsics=dict(FR1, fx_px=math.nan))),
            ),
            (
                "infinite_depth_scale",
                "depth_scale +inf",
                "Handshake",
                raw("Handshake", handshake("DEPTH", depth_scale_units_per_m=math.inf)),
            ),
            (
                "stream_kind_mismatch",
                "RGB stream announcing DEPTH16",
                "Handshake",
                raw("Handshake", handshake("RGB", pixel_format="DEPTH16")),
            ),
            (
                "non_ascii_device_id",
                "device_id with byte 0xC3",
                "Handshake",
                raw("Handshake", handshake("RGB", device_id="cam\u00e9")),
            ),
            (
                "non_unit_quaternion",
                "T_world_cam q = (0,0,0,0.5)",
                "PoseUpdate",
                raw(
                    "PoseUpdate",
                    pose_update(
                        T_world_cam={"t_m": [0.0, 0.0, 0.0], "q_xyzw": [0.0, 0.0, 0.0, 0.5]}
                    ),
                ),
            ),
            (
                "invalid_tracking_state",
                "tracking_state 9",
                "PoseUpdate",
                raw("PoseUpdate", pose_update(tracking_state=9)),
            ),
            (
                "invalid_edge_kind",
                "edge kind 5",
                "PoseGraph",
                raw(
                    "PoseGraph", dict(pose_graph(), edges=[dict(pose_graph()["edges"][0], kind=5)])
                ),
            ),
            (
                "map_cells_size_mismatch",
                "4x3 map with 11 cells",
                "FloorMap",
                raw("FloorMap", dict(floor_map(), cells=bytes(11))),
            ),
            (
                "rgbd_attitude_not_unit",
                "RgbdFrame attitude q = (0,0,0,0.5)",
                "RgbdFrame",
                raw("RgbdFrame", rgbd_frame({"valid": True, "q_xyzw": [0.0, 0.0, 0.0, 0.5]})),
            ),
            (
                "rgbd_swapped_images",
                "RgbdFrame with depth in the rgb slot",
                "RgbdFrame",
                raw(
                    "RgbdFrame",
                    dict(rgbd_frame(), rgb=rgbd_frame()["depth"], depth=rgbd_frame()["rgb"]),
                ),
            ),
            (
                "accel_not_finite",
                "Frame accel f_mps2 x = NaN",
                "Frame",
                raw(
                    "Frame",
                    {
                        "image": image("RGB8"),
                        "accel": dict(KINECT_LEVEL_ACCEL, f_mps2=[math.nan, 9.8, 0.0]),
                    },
                ),
            ),
            (
                "accel_out_of_range",
                "RgbdFrame accel f_mps2 z = 2000 m/s^2",
                "RgbdFrame",
                raw(
                    "RgbdFrame",
                    rgbd_frame(accel=dict(KINECT_LEVEL_ACCEL, f_mps2=[0.0, 9.8, 2000.0])),
                ),
            ),
        ]
        pu = bytearray(c.encode_body("PoseUpdate", pose_update()))
        pu[-9] = 2  # is_keyframe = 2 (before inlier_count and map_correction_count, u32 each)
        invalid.append(("bool_not_0_or_1", "is_keyframe byte 2", "PoseUpdate", bytes(pu)))
        for name, description, msg_name, body in invalid:
            self.hostile_body(name, description, msg_name, body, "invalid_value")

        # Garbage and resynchronisation.
        garbage = b"\x00\xffhello RGB" + b"RG"
        self.add(
            "garbage_before_frame",
            "13 bytes of garbage (with partial magics) then a frame",
            garbage + req,
            [
                self.expect_err("garbage_skipped", len(garbage)),
                self.expect_msg("FrameRequest", {"credits": 1, "last_received_sequence": 3}),
            ],
        )
        self.add(
            "garbage_only",
            "garbage ending in a partial magic 'RG' (kept, waiting)",
            b"noise noise RG",
            [self.expect_err("garbage_skipped", 12)],
            buffered=2,
        )
        fake = c.spec.magic + b"\x01\x03\x00\x00" + bytes(8)
        self.add(
            "fake_magic_then_frame",
            "a magic followed by a bad header, then a request",
            fake + req,
            [
                self.expect_err("bad_header_crc", len(fake)),
                self.expect_msg("FrameRequest", {"credits": 1, "last_received_sequence": 3}),
            ],
        )

    def check_with_python_decoder(self):
        """The hand-written expectations must hold for the Python decoder (whole and by byte)."""
        for v in self.vectors:
            data = self.files[v["file"]]
            for chunk in (len(data) or 1, 1):
                dec = StreamDecoder(self.codec)
                events = []
                for i in range(0, len(data), chunk):
                    dec.feed(data[i : i + chunk])
                    events += [event_view(self.codec, e) for e in dec.drain()]
                got = {"events": normalize_events(events), "buffered_bytes": dec.buffered_bytes}
                if got != v["expected"]:
                    raise SystemExit(
                        f"vector {v['name']} (chunk {chunk}): python decoder gives "
                        f"{json.dumps(got)[:600]}"
                    )
            for e in v["expected"]["events"]:
                if "refused" in v and e["event"] == "message":
                    _, fields = self.codec.from_view(e["message"])
                    if v["refused"] not in self.codec.incompatibility(fields):
                        raise SystemExit(f"vector {v['name']}: not refused")

    def outputs(self) -> dict[Path, bytes]:
        out = {VECTORS / k: v for k, v in self.files.items()}
        manifest = {
            "about": "Golden vectors of protocol/spec/messages.json, generated by "
            "protocol/tools/make_vectors.py. Each file is a byte stream; 'expected' lists "
            "the StreamDecoder events for it (error 'detail' text is not compared) and "
            "the bytes left buffered, compared after merging each garbage_skipped event into "
            "a directly preceding error (so any chunking of the stream gives the same events); "
            "'refused' means the message decodes but the "
            "peer-compatibility check must refuse it with that reason.",
            "schema_hash": f"0x{self.codec.spec.schema_hash:016x}",
            "stream_auth": {
                "about": "Every Handshake and HandshakeAck message in the vectors is signed "
                "with this key and these nonces (protocol.stream_auth), except those named "
                "in 'forged', whose mac must not verify.",
                "key": AUTH_KEY.hex(),
                "receiver_nonce": RECEIVER_NONCE.hex(),
                "sender_nonce": SENDER_NONCE.hex(),
                "forged": ["handshake_bad_mac", "handshake_unsigned"],
            },
            "vectors": self.vectors,
        }
        out[VECTORS / "manifest.json"] = (json.dumps(manifest, indent=1) + "\n").encode()
        for target, bodies in self.bodies.items():
            for name, body in bodies.items():
                out[VECTORS / "corpus" / target / f"{name}.bin"] = body
        return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--check",
        action="store_true",
        help="exit 1 if the committed vectors differ from what this generates",
    )
    args = parser.parse_args()
    b = Builder()
    b.build()
    b.check_with_python_decoder()
    outputs = b.outputs()
    if args.check:
        stale = [str(p) for p, data in outputs.items() if not p.exists() or p.read_bytes() != data]
        if stale:
            print(
                "stale vectors (run python3 protocol/tools/make_vectors.py):",
                *stale[:10],
                sep="\n  ",
                file=sys.stderr,
            )
            return 1
        return 0
    for path, data in outputs.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    print(
        f"wrote {len(b.vectors)} vectors and {len(outputs) - len(b.vectors) - 1} corpus seeds "
        f"to {VECTORS}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
