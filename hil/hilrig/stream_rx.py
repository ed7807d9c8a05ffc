"""A minimal ground-station receiver of the RGB-D stream, in Python, for HIL scenarios.

Listens on loopback for the two connections rgbd-streamer opens (RGB, depth), challenges each one
and accepts only a handshake signed with the stream key (protocol.stream_auth), answers it,
grants credits the way docs/protocol.md prescribes (2 at start, 1 per frame taken off the socket)
and records every frame with its receive time on CLOCK_MONOTONIC, the clock rgbd-streamer stamps
send_timestamp_us with (same host), so send -> receive latency is measurable.
`drop()` closes the connections and the listeners (link dropped); `restore()` listens again on the
same ports. One thread per stream; `close()` joins them. Protocol: rgbd_protocol (the spec's codec).
"""

from __future__ import annotations

import os
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from rgbd_protocol.codec import Codec, StreamDecoder
from rgbd_protocol.stream_auth import ack_tag, handshake_tag, load_key_file, tags_equal

INITIAL_CREDITS = 2  # docs/protocol.md: one frame in flight while the next is produced


@dataclass(frozen=True)
class ReceivedFrame:
    kind: str  # "rgb" | "depth"
    sequence: int
    capture_timestamp_us: int
    send_timestamp_us: int
    receive_monotonic_us: int
    width: int
    height: int
    payload: bytes


class _StreamPort:
    def __init__(self, kind: str, owner: "StreamReceiver", port: int = 0) -> None:
        self.kind = kind
        self.owner = owner
        self.listener = socket.create_server(("127.0.0.1", port), reuse_port=False)
        self.listener.settimeout(0.2)
        self.port = self.listener.getsockname()[1]
        self.conn: socket.socket | None = None
        self.thread = threading.Thread(target=self._run, name=f"rx-{kind}", daemon=True)
        self.stop = threading.Event()
        self.thread.start()

    def _run(self) -> None:
        codec = self.owner.codec
        while not self.stop.is_set():
            try:
                conn, _ = self.listener.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return
            self.conn = conn
            self.owner._note(f"{self.kind}: connected")
            try:
                self._serve(conn, codec)
            except OSError:
                pass
            finally:
                conn.close()
                self.conn = None
                self.owner._note(f"{self.kind}: disconnected")

    def _serve(self, conn: socket.socket, codec: Codec) -> None:
        conn.settimeout(0.2)
        nonce = os.urandom(16)  # the challenge: fresh per connection
        conn.sendall(codec.encode("StreamChallenge", {"receiver_nonce": list(nonce)}))
        dec = StreamDecoder(codec)
        while not self.stop.is_set():
            try:
                data = conn.recv(1 << 20)
            except (TimeoutError, socket.timeout):
                continue
            if not data:
                return
            now_us = time.monotonic_ns() // 1000
            dec.feed(data)
            while True:
                ev = dec.next()
                if ev.kind == "need_more":
                    break
                if ev.kind == "error":
                    self.owner._note(f"{self.kind}: decode error {ev.error}")
                    continue
                if ev.name == "Handshake":
                    self.owner._handshake(self.kind, ev.fields)
                    reason = codec.incompatibility(ev.fields)
                    expected = handshake_tag(codec, self.owner.key, nonce, ev.fields)
                    if not tags_equal(ev.fields["mac"], expected):
                        reason = "handshake not authenticated (wrong stream key?)"
                    ack = {"accepted": not reason, "reason": reason, "mac": [0] * 8}
                    ack["mac"] = ack_tag(
                        codec, self.owner.key, nonce, bytes(ev.fields["sender_nonce"]), ack
                    )
                    conn.sendall(codec.encode("HandshakeAck", ack))
                    if reason:
                        self.owner._note(f"{self.kind}: refused handshake: {reason}")
                        return
                    conn.sendall(
                        codec.encode(
                            "FrameRequest",
                            {"credits": INITIAL_CREDITS, "last_received_sequence": 0},
                        )
                    )
                elif ev.name == "Frame":
                    im = ev.fields["image"]
                    self.owner._add(
                        ReceivedFrame(
                            self.kind,
                            im["sequence"],
                            im["capture_timestamp_us"],
                            im["send_timestamp_us"],
                            now_us,
                            im["width"],
                            im["height"],
                            bytes(im["payload"]),
                        )
                    )
                    conn.sendall(
                        codec.encode(
                            "FrameRequest", {"credits": 1, "last_received_sequence": im["sequence"]}
                        )
                    )

    def shutdown(self) -> None:
        self.stop.set()
        try:
            self.listener.close()
        except OSError:
            pass
        c = self.conn
        if c is not None:
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        self.thread.join(timeout=5)


class StreamReceiver:
    def __init__(self, key_file: Path | str) -> None:
        """`key_file`: the stream key (protocol.stream_auth), the same file the streamer reads."""
        self.codec = Codec()
        self.key = load_key_file(key_file)
        self._lock = threading.Lock()
        self._frames: list[ReceivedFrame] = []
        self._notes: list[tuple[int, str]] = []
        self.handshakes: dict[str, dict] = {}
        self._ports = {k: _StreamPort(k, self) for k in ("rgb", "depth")}
        self.rgb_port = self._ports["rgb"].port
        self.depth_port = self._ports["depth"].port

    def _add(self, f: ReceivedFrame) -> None:
        with self._lock:
            self._frames.append(f)

    def _handshake(self, kind: str, fields: dict) -> None:
        with self._lock:
            self.handshakes[kind] = fields

    def _note(self, text: str) -> None:
        with self._lock:
            self._notes.append((time.monotonic_ns() // 1000, text))

    def frames(self, kind: str | None = None) -> list[ReceivedFrame]:
        with self._lock:
            return [f for f in self._frames if kind is None or f.kind == kind]

    def notes(self) -> list[tuple[int, str]]:
        with self._lock:
            return list(self._notes)

    def drop(self) -> None:
        """The link goes down: connections and listeners close (the sender sees resets/refusals)."""
        for p in self._ports.values():
            p.shutdown()

    def restore(self) -> None:
        """The link comes back: listen again on the same ports."""
        self._ports = {
            k: _StreamPort(k, self, port)
            for k, port in (("rgb", self.rgb_port), ("depth", self.depth_port))
        }

    def close(self) -> None:
        for p in self._ports.values():
            p.shutdown()

    def __enter__(self) -> "StreamReceiver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
