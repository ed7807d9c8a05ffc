"""slam-server under faults and hostile peers, over loopback TCP with the Python protocol codec.

Each test starts its own slam-server on a free port (short timeouts given on the command line so
nothing waits long), stops it by PID, and reads its log (stderr) to check that every connection
that ended says why. Deadlines in the tests are generous (the machine is shared); nothing asserts
a wall-clock duration beyond "it happened before the deadline".

  * a broken connection does not discard the map: the same map id (SlamHello.session_id)
    reconnects and continues (SlamHello.resumed, session_frames; the next pose is tracked, not
    INITIALIZING);
  * nor does a killed slam-server, given --checkpoint-dir: the next one resumes the map from its
    checkpoint and tracks the next frame in it;
  * a newer connection with the same map id takes it over; the old one is closed with the cause;
  * an idle client does not block another one;
  * a client that never says hello, stops mid-message or drips bytes is closed with the cause;
  * every RgbdFrame gets exactly one PoseUpdate, LOST when the frame cannot be used;
  * with all client slots busy a newcomer is refused with a reason in SlamHello.refusal.
Skipped when the binary is not built (SLAM_SERVER=path overrides build/bin/slam-server).
"""

import os
import signal
import socket
import subprocess
import tempfile
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
DEADLINE_S = 30.0  # generous: the shared 2-core machine may be busy

pytestmark = pytest.mark.skipif(not BINARY.exists(), reason=f"{BINARY} not built")
CODEC = Codec()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def texture(seed: int = 42) -> np.ndarray:
    rng = np.random.default_rng(seed)
    blocks = rng.integers(0, 256, size=(H // 8, (W + 256) // 8, 3), dtype=np.uint8)
    return np.repeat(np.repeat(blocks, 8, axis=0), 8, axis=1)


def frame_bytes(seq: int, tex: np.ndarray, encoding: str = "RAW") -> bytes:
    rgb = np.ascontiguousarray(tex[:, seq * 4 : seq * 4 + W])
    depth = np.full((H, W), DEPTH_UNITS_PER_M, dtype="<u2")

    def image(fmt, payload, enc="RAW"):
        return {
            "sequence": seq,
            "capture_timestamp_us": 1_000_000 + seq * 33_333,
            "send_timestamp_us": 0,
            "width": W,
            "height": H,
            "pixel_format": fmt,
            "encoding": enc,
            "payload": payload,
        }

    rgb_image = image("RGB8", rgb.tobytes())
    if encoding != "RAW":
        rgb_image = image("RGB8", b"\xff\xd8\xff\xe0" + bytes(60) + b"\xff\xd9", encoding)
    return CODEC.encode(
        "RgbdFrame",
        {
            "pair_sequence": 10 + seq,
            "intrinsics": {**TUM_FR1.intrinsics(), "distortion": [0.0] * 5},
            "depth_scale_units_per_m": float(DEPTH_UNITS_PER_M),
            "attitude": {"valid": False, "q_xyzw": [0.0, 0.0, 0.0, 1.0]},
            "rgb": rgb_image,
            "depth": image("DEPTH16", depth.tobytes()),
        },
    )


def hello_bytes(session_id: int, name: str = "pytest") -> bytes:
    return CODEC.encode(
        "SlamHello",
        {
            "protocol_version": CODEC.spec.version,
            "schema_hash": CODEC.spec.schema_hash,
            "peer_name": name,
            "session_id": session_id,
            "resumed": False,
            "session_frames": 0,
            "refusal": "",
        },
    )


class Server:
    def __init__(self, *extra: str, backend: str = "vo"):
        self.port = free_port()
        self.log_file = tempfile.NamedTemporaryFile(
            prefix="slam-server-", suffix=".log", delete=False
        )
        self.proc = subprocess.Popen(
            [
                str(BINARY),
                "--bind",
                "127.0.0.1",
                "--port",
                str(self.port),
                "--features",
                "orb",
                "--backend",
                backend,
                *extra,
            ],
            stderr=self.log_file,
        )
        deadline = time.monotonic() + DEADLINE_S
        while "listening" not in self.log():
            assert self.proc.poll() is None, self.log()
            assert time.monotonic() < deadline, "slam-server did not start listening"
            time.sleep(0.05)

    def log(self) -> str:
        return Path(self.log_file.name).read_text()

    def wait_log(self, text: str) -> str:
        deadline = time.monotonic() + DEADLINE_S
        while text not in self.log():
            assert time.monotonic() < deadline, f"'{text}' not in the log:\n{self.log()}"
            time.sleep(0.05)
        return self.log()

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout=DEADLINE_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise
        finally:
            os.unlink(self.log_file.name)


@pytest.fixture
def server_factory():
    started = []

    def make(*extra, backend: str = "vo"):
        s = Server(*extra, backend=backend)
        started.append(s)
        return s

    yield make
    for s in started:
        assert s.stop() == 0


class Client:
    def __init__(self, port: int):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=DEADLINE_S)
        self.dec = StreamDecoder(CODEC)
        self.pending = []

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def next_message(self):
        while not self.pending:
            data = self.sock.recv(65536)
            assert data, "slam-server closed the connection"
            self.dec.feed(data)
            self.pending += [e for e in self.dec.drain() if e.kind == "message"]
        return self.pending.pop(0)

    def hello(self, session_id: int):
        self.send(hello_bytes(session_id))
        m = self.next_message()
        assert m.name == "SlamHello"
        return m.fields

    def closed_by_peer(self) -> bool:
        """True once the server closed (EOF or reset) before the deadline."""
        self.sock.settimeout(DEADLINE_S)
        try:
            while True:
                data = self.sock.recv(65536)
                if not data:
                    return True
        except ConnectionResetError:
            return True
        except socket.timeout:
            return False

    def close(self) -> None:
        self.sock.close()


def test_broken_connection_resumes_the_same_map(server_factory):
    # GIVEN a client that sent 3 frames to map 0x12AB
    srv = server_factory()
    tex = texture()
    a = Client(srv.port)
    h = a.hello(0x12AB)
    assert h["session_id"] == 0x12AB and not h["resumed"] and h["refusal"] == ""
    for seq in range(3):
        a.send(frame_bytes(seq, tex))
        assert a.next_message().name == "PoseUpdate"
    # WHEN its connection breaks and it reconnects with the same map id
    a.close()
    srv.wait_log("closed: peer closed the connection (end of file)")
    b = Client(srv.port)
    h = b.hello(0x12AB)
    # THEN the map continues: resumed, 3 frames in it, the next pose is tracked (not initialising)
    assert h["resumed"] and h["session_frames"] == 3 and h["session_id"] == 0x12AB
    b.send(frame_bytes(3, tex))
    u = b.next_message()
    assert u.name == "PoseUpdate" and u.fields["pair_sequence"] == 13
    assert u.fields["tracking_state"] == "TRACKING"
    assert "map 00000000000012ab resumed (world frame kept, 3 frames" in srv.log()
    b.close()


def test_killed_server_with_checkpoints_is_resumed_by_the_next_one(tmp_path):
    # GIVEN a slam-server that checkpoints its maps, and a client that sent 3 frames to map 0x77
    ckpt = tmp_path / "checkpoints"
    first = Server("--checkpoint-dir", str(ckpt), backend="localmap")
    tex = texture()
    a = Client(first.port)
    assert not a.hello(0x77)["resumed"]
    for seq in range(3):
        a.send(frame_bytes(seq, tex))
        assert a.next_message().fields["tracking_state"] == "TRACKING"
    path = ckpt / "map-0000000000000077.map"
    deadline = time.monotonic() + DEADLINE_S
    while not path.exists():  # written by the map's mapping side after its first keyframe
        assert time.monotonic() < deadline, first.log()
        time.sleep(0.05)
    # WHEN it is killed (no goodbye, no final save) and a new one is started on the same folder
    first.proc.kill()
    first.proc.wait(timeout=DEADLINE_S)
    a.close()
    os.unlink(first.log_file.name)
    second = Server("--checkpoint-dir", str(ckpt), backend="localmap")
    try:
        b = Client(second.port)
        h = b.hello(0x77)
        # THEN the map resumes from its checkpoint and the next frame is tracked in that map
        assert h["resumed"] and h["session_id"] == 0x77, second.log()
        assert "map 0000000000000077 resumed from its checkpoint" in second.log()
        b.send(frame_bytes(3, tex))
        assert b.next_message().fields["tracking_state"] == "TRACKING", second.log()
        b.close()
        # AND another id starts a new map
        c = Client(second.port)
        assert not c.hello(0x78)["resumed"]
        c.close()
    finally:
        assert second.stop() == 0


def test_new_connection_with_the_same_map_id_takes_it_over(server_factory):
    srv = server_factory()
    a = Client(srv.port)
    a.hello(0x77)
    b = Client(srv.port)
    h = b.hello(0x77)
    assert h["resumed"]
    assert a.closed_by_peer()
    srv.wait_log("map taken over by client #2")
    b.close()


def test_idle_client_does_not_block_another(server_factory):
    srv = server_factory()
    idle = Client(srv.port)
    idle.hello(1)  # then says nothing
    busy = Client(srv.port)
    busy.hello(2)
    busy.send(frame_bytes(0, texture()))
    assert busy.next_message().name == "PoseUpdate"
    idle.close()
    busy.close()


def test_silent_client_is_closed_with_a_cause(server_factory):
    srv = server_factory("--hello-timeout-ms", "300")
    c = Client(srv.port)
    assert c.closed_by_peer()
    assert "closed: no SlamHello within 300 ms of connecting" in srv.wait_log("no SlamHello")
    c.close()


def test_client_that_stops_mid_message_is_closed_with_a_cause(server_factory):
    srv = server_factory("--message-timeout-ms", "500")
    c = Client(srv.port)
    c.hello(5)
    c.send(frame_bytes(0, texture())[:100_000])
    assert c.closed_by_peer()
    assert "a message begun and not finished within 500 ms (100000 bytes" in srv.wait_log(
        "begun and not finished"
    )
    c.close()


def test_dripping_client_is_closed_with_a_cause(server_factory):
    srv = server_factory("--message-timeout-ms", "500", "--idle-timeout-ms", "60000")
    c = Client(srv.port)
    c.hello(6)
    data = frame_bytes(0, texture())
    deadline = time.monotonic() + DEADLINE_S
    closed = False
    for i in range(0, len(data), 10):  # 10 bytes every 20 ms: the idle timer never fires
        try:
            c.send(data[i : i + 10])
        except (BrokenPipeError, ConnectionResetError):
            closed = True
            break
        if "begun and not finished" in srv.log():
            closed = True
            break
        assert time.monotonic() < deadline
        time.sleep(0.02)
    assert closed
    srv.wait_log("begun and not finished within 500 ms")
    c.close()


def test_every_frame_gets_one_pose_update_even_unusable_ones(server_factory):
    srv = server_factory()
    c = Client(srv.port)
    c.hello(7)
    c.send(frame_bytes(0, texture(), encoding="RGB_JPEG"))  # slam-server takes RAW only
    u = c.next_message()
    assert u.name == "PoseUpdate" and u.fields["pair_sequence"] == 10
    assert u.fields["tracking_state"] == "LOST" and u.fields["inlier_count"] == 0
    assert "answered LOST: slam-link: only RAW" in srv.wait_log("answered LOST")
    c.close()


def test_all_slots_busy_refuses_a_newcomer_with_a_reason(server_factory):
    srv = server_factory("--max-clients", "1")
    a = Client(srv.port)
    a.hello(8)
    b = Client(srv.port)  # a has just spoken: not idle, so it is not evicted
    m = b.next_message()
    assert m.name == "SlamHello" and "busy" in m.fields["refusal"]
    assert b.closed_by_peer()
    a.send(frame_bytes(0, texture()))
    assert a.next_message().name == "PoseUpdate"
    a.close()
    b.close()
