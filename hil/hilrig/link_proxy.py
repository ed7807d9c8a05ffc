"""A degraded network link in user space: a loopback TCP proxy that delays and "loses" data.

The kernel's netem qdisc is not available on this machine (and would shape every process's
loopback),
so link faults are emulated here, per link, for the processes a scenario starts. TCP never shows
loss to the application: a lost segment shows up as a stall of one retransmission timeout (Linux's
minimum RTO is 200 ms) after which the data arrives in order. So each chunk forwarded is delayed by
`delay_ms` (+ uniform `jitter_ms`), and with probability `loss` it is held an extra `rto_ms`; order
is kept (a stalled chunk holds back the ones behind it, as TCP's in-order delivery does).
`sever()` drops every connection and refuses new ones until `restore()`. `stall(seconds)` holds
every chunk for that long (a WiFi link that stops carrying data and then delivers the backlog, as
TCP does after a stall); `impairment` may be replaced while the proxy runs.
Randomness: one seeded generator per proxy. Wall clock: read through the `clock` passed in (the
proxy is a real-time component between real processes). Threads are joined by close().
"""

from __future__ import annotations

import random
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass

LINUX_MIN_RTO_MS = 200.0  # TCP_RTO_MIN


@dataclass(frozen=True)
class LinkImpairment:
    delay_ms: float = 0.0  # one-way, each direction
    jitter_ms: float = 0.0  # uniform 0..jitter added per chunk
    loss: float = 0.0  # probability a chunk needs a retransmission
    rto_ms: float = LINUX_MIN_RTO_MS
    seed: int = 1

    def validate(self) -> None:
        if self.delay_ms < 0 or self.jitter_ms < 0 or self.rto_ms < 0:
            raise ValueError("LinkImpairment delays must be >= 0")
        if not 0 <= self.loss < 1:
            raise ValueError("LinkImpairment.loss must be in [0, 1)")


class _Pipe:
    """One direction of one connection: reader thread queues (release_time, bytes); writer sends."""

    def __init__(self, src: socket.socket, dst: socket.socket, proxy: "LinkProxy") -> None:
        self.src, self.dst, self.proxy = src, dst, proxy
        self.queue: deque[tuple[float, bytes]] = deque()
        self.cv = threading.Condition()
        self.closed = False
        self.finished = False  # the writer is done: nothing more goes through this direction
        self.threads = [
            threading.Thread(target=self._read, daemon=True),
            threading.Thread(target=self._write, daemon=True),
        ]
        for t in self.threads:
            t.start()

    def _read(self) -> None:
        last = 0.0
        try:
            while True:
                data = self.src.recv(65536)
                if not data:
                    break
                release = max(self.proxy._release_time(), last)
                last = release
                with self.cv:
                    self.queue.append((release, data))
                    self.cv.notify()
        except OSError:
            pass
        with self.cv:
            self.closed = True
            self.cv.notify()

    def _write(self) -> None:
        clock = self.proxy.clock
        try:
            while True:
                with self.cv:
                    while not self.queue and not self.closed:
                        self.cv.wait(0.1)
                    if not self.queue and self.closed:
                        break
                    release, data = self.queue[0]
                wait = release - clock()
                if wait > 0:
                    time.sleep(min(wait, 0.01))
                    continue
                with self.cv:
                    self.queue.popleft()
                self.dst.sendall(data)
        except OSError:
            pass
        try:
            self.dst.shutdown(socket.SHUT_WR)
        except OSError:
            pass
        self.finished = True


class LinkProxy:
    def __init__(
        self,
        upstream_port: int,
        impairment: LinkImpairment = LinkImpairment(),  # noqa: B008 (frozen dataclass)
        clock=time.monotonic,
    ) -> None:
        impairment.validate()
        self.upstream_port = upstream_port
        self.impairment = impairment
        self.clock = clock
        self._rng = random.Random(impairment.seed)
        self._rng_lock = threading.Lock()
        self._lock = threading.Lock()
        self._conns: list[tuple[socket.socket, socket.socket, _Pipe, _Pipe]] = []
        self.stalls = 0
        self.chunks = 0
        self._stall_until = 0.0  # clock() before which nothing is released (stall())
        self._listener: socket.socket | None = None
        self.port = 0
        self._stop = threading.Event()
        self._accept_thread: threading.Thread | None = None
        self._listen()

    def _listen(self, port: int = 0) -> None:
        self._listener = socket.create_server(("127.0.0.1", port))
        self._listener.settimeout(0.1)
        self.port = self._listener.getsockname()[1]
        self._stop.clear()
        self._accept_thread = threading.Thread(target=self._accept, daemon=True)
        self._accept_thread.start()

    def _release_time(self) -> float:
        imp = self.impairment
        with self._rng_lock:
            extra = imp.jitter_ms * self._rng.random()
            lost = self._rng.random() < imp.loss
            self.chunks += 1
            if lost:
                self.stalls += 1
        release = self.clock() + (imp.delay_ms + extra + (imp.rto_ms if lost else 0.0)) / 1000.0
        return max(release, self._stall_until)

    def stall(self, seconds: float) -> None:
        """The link carries nothing for `seconds` from now; what is sent meanwhile arrives in order
        when the stall ends (connections stay open)."""
        if not seconds >= 0:
            raise ValueError("stall seconds must be >= 0")
        with self._rng_lock:
            self._stall_until = max(self._stall_until, self.clock() + seconds)

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                client, _ = self._listener.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return
            try:
                upstream = socket.create_connection(("127.0.0.1", self.upstream_port), timeout=2)
                upstream.settimeout(None)
            except OSError:
                client.close()
                continue
            client.settimeout(None)
            with self._lock:
                self._close_finished()
                self._conns.append(
                    (client, upstream, _Pipe(client, upstream, self), _Pipe(upstream, client, self))
                )

    def _close_finished(self) -> None:
        """Caller holds _lock. Closes the sockets of connections finished both ways: a client that
        opens a connection per request (quad-control's firmware link does, `Connection: close`)
        would otherwise leave two descriptors behind per request (~60 a second)."""
        keep = []
        for conn in self._conns:
            a, b, p1, p2 = conn
            if p1.finished and p2.finished:
                a.close()
                b.close()
            else:
                keep.append(conn)
        self._conns = keep

    def sever(self) -> None:
        """The link goes down: every connection is reset and the port refuses new ones."""
        self._stop.set()
        if self._listener is not None:
            self._listener.close()
        if self._accept_thread is not None:
            self._accept_thread.join(timeout=2)
        with self._lock:
            conns, self._conns = self._conns, []
        for a, b, p1, p2 in conns:
            for s in (a, b):
                try:
                    s.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                s.close()
            for t in p1.threads + p2.threads:
                t.join(timeout=2)

    def restore(self) -> None:
        self._listen(self.port)

    def close(self) -> None:
        self.sever()

    def __enter__(self) -> "LinkProxy":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
