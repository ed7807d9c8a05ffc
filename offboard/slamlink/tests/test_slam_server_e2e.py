"""slam-server end to end over loopback TCP with the project's Python protocol codec.

GIVEN slam-server listening on 127.0.0.1, WHEN a client sends SlamHello and three RgbdFrames
(a seeded random texture on a plane 1 m away, shifted 4 px per frame), THEN it answers with its own
SlamHello and exactly one PoseUpdate per frame, in order; SIGTERM (by PID) stops it with exit 0.
Skipped when the binary is not built (SLAM_SERVER=path overrides build/bin/slam-server).
"""

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from rgbd_protocol import Codec, StreamDecoder
from rgbd_protocol.tum_cameras import TUM_DEPTH_UNITS_PER_M, TUM_FR1

REPO = Path(__file__).resolve().parents[3]
BINARY = Path(os.environ.get("SLAM_SERVER", REPO / "build" / "bin" / "slam-server"))
W, H = 640, 480
DEPTH_UNITS_PER_M = int(TUM_DEPTH_UNITS_PER_M)  # TUM convention: a flat wall at 1 m


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def frame_fields(seq: int, texture: np.ndarray) -> dict:
    rgb = np.ascontiguousarray(texture[:, seq * 4 : seq * 4 + W])
    depth = np.full((H, W), DEPTH_UNITS_PER_M, dtype="<u2")

    def image(fmt, payload):
        return {
            "sequence": seq,
            "capture_timestamp_us": 1_000_000 + seq * 33_333,
            "send_timestamp_us": 0,
            "width": W,
            "height": H,
            "pixel_format": fmt,
            "encoding": "RAW",
            "payload": payload,
        }

    return {
        "pair_sequence": 10 + seq,
        "intrinsics": {**TUM_FR1.intrinsics(), "distortion": [0.0] * 5},
        "depth_scale_units_per_m": float(DEPTH_UNITS_PER_M),
        # a craft's IMU attitude (level, heading north): the tracker's rotation prior path
        "attitude": {"valid": True, "q_xyzw": [0.5, 0.5, 0.5, 0.5]},
        "rgb": image("RGB8", rgb.tobytes()),
        "depth": image("DEPTH16", depth.tobytes()),
    }


@pytest.mark.skipif(not BINARY.exists(), reason=f"{BINARY} not built")
def test_slam_server_answers_each_frame_with_one_pose_update():
    codec = Codec()
    rng = np.random.default_rng(42)
    # Blocky random texture (8 px blocks) so ORB finds corners that survive a 4 px shift.
    blocks = rng.integers(0, 256, size=(H // 8, (W + 64) // 8, 3), dtype=np.uint8)
    texture = np.repeat(np.repeat(blocks, 8, axis=0), 8, axis=1)
    port = free_port()
    proc = subprocess.Popen(
        [
            str(BINARY),
            "--bind",
            "127.0.0.1",
            "--port",
            str(port),
            "--features",
            "orb",
            "--backend",
            "glc",
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 20
        while True:
            try:
                sock = socket.create_connection(("127.0.0.1", port), timeout=2)
                break
            except OSError:
                assert proc.poll() is None, proc.stderr.read()
                assert time.monotonic() < deadline, "slam-server did not start listening"
                time.sleep(0.1)
        sock.settimeout(60)
        dec = StreamDecoder(codec)
        sock.sendall(
            codec.encode(
                "SlamHello",
                {
                    "protocol_version": codec.spec.version,
                    "schema_hash": codec.spec.schema_hash,
                    "peer_name": "pytest",
                    "session_id": 0,
                    "resumed": False,
                    "session_frames": 0,
                    "refusal": "",
                },
            )
        )
        for seq in range(3):
            sock.sendall(codec.encode("RgbdFrame", frame_fields(seq, texture)))
        messages = []
        while len(messages) < 4:
            data = sock.recv(65536)
            assert data, "slam-server closed the connection"
            dec.feed(data)
            messages += [e for e in dec.drain() if e.kind == "message"]
        sock.close()
        assert messages[0].name == "SlamHello"
        updates = messages[1:]
        assert [m.name for m in updates] == ["PoseUpdate"] * 3
        assert [m.fields["pair_sequence"] for m in updates] == [10, 11, 12]
        assert updates[0].fields["tracking_state"] == "INITIALIZING"
        for m in updates:
            assert all(np.isfinite(m.fields["T_world_cam"]["t_m"]))
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            code = proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
    assert code == 0
