"""WiFi-bridge emulator: an HTTP server on loopback that speaks the bridge chip's link.

The reference of the control link's HTTP <-> serial-line mapping (control_spec.json serial_link),
kept with the codec so every side's tests use the same one: the HIL rig fronts the firmware in
simavr with it, the ground-station tests front a firmware double (it lives here because deployables
share only contracts). As specified in docs/protocol-control.md: each HTTP request becomes ONE text
line `<METHOD> <target>` on the ATmega's serial link (no HTTP version, headers or body); the one
reply line `<status> <json>` comes back as the HTTP response (status code + JSON body). One request
at a time on the serial link. What the serial side is comes in as a callable
`transact(line: str, timeout_s: float) -> str | None` (None: no reply in time), so the same bridge
fronts the firmware in simavr (hilrig.live_rig) or a test double.

Behaviour this emulator defines where the real chip's is not documented (docs/hil.md):
  * a request the HTTP parser rejects (bad request line, bad version, oversized header) gets the
    parser's 400/414/431 and never reaches the serial link;
  * a request body is read and dropped (the line carries none);
  * no reply line within reply_timeout_ms -> 504 (gateway timeout) with a JSON error body;
  * a reply line that is not `<status> <json>` -> 502.
Thread safety: HTTP requests are served on a thread each; the serial link is serialised by a lock.
Start/stop: `start()` binds 127.0.0.1 (port 0 = any free port, see `.port`), `close()` stops and
joins.
"""

from __future__ import annotations

import json
import re
import threading
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Callable

Transact = Callable[[str, float], "str | None"]

_REPLY_RE = re.compile(r"^([1-5][0-9]{2}) (\{.*\})$")
# Methods forwarded to the firmware (it answers 405/404 for the ones it does not serve).
FORWARDED_METHODS = ("GET", "PUT", "POST", "DELETE", "PATCH", "HEAD", "OPTIONS")


@dataclass(frozen=True)
class BridgeOptions:
    port: int = 0
    # A control reply is useless after 100 ms (quad-control's own timeout); 250 ms leaves room for a
    # request queued behind another one on the single serial link.
    reply_timeout_ms: float = 250.0
    # Request bodies above this are refused before reading (the chip has a few KB of RAM).
    max_body_bytes: int = 4096

    def validate(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ValueError(f"BridgeOptions.port out of range: {self.port}")
        if not self.reply_timeout_ms > 0:
            raise ValueError("BridgeOptions.reply_timeout_ms must be > 0")
        if self.max_body_bytes < 0:
            raise ValueError("BridgeOptions.max_body_bytes must be >= 0")


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # keep-alive, as quad-control's two clients expect
    # Error replies to unparsable requests still carry a status line (http.server would otherwise
    # answer a request it takes for HTTP/0.9 with a bare body).
    default_request_version = "HTTP/1.0"
    server_version = "rgbdquad-bridge-emulator/1"

    def log_message(self, fmt, *args) -> None:  # the scenarios count requests instead
        pass

    def _send(self, status: int, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _forward(self) -> None:
        bridge: WifiBridgeEmulator = self.server.bridge  # type: ignore[attr-defined]
        length = self.headers.get("Content-Length")
        if length is not None:
            try:
                n = int(length)
            except ValueError:
                n = -1
            if n < 0 or n > bridge.options.max_body_bytes:
                bridge._count("refused_body")
                self._send(413, b'{"err":"body_too_large"}')
                self.close_connection = True
                return
            self.rfile.read(n)
        line = f"{self.command} {self.path}"
        reply = bridge._transact(line)
        if reply is None:
            bridge._count("timeout")
            self._send(504, b'{"err":"no_reply_from_firmware"}')
            return
        m = _REPLY_RE.match(reply.rstrip("\r\n"))
        if not m:
            bridge._count("bad_reply")
            self._send(502, json.dumps({"err": "bad_reply_line", "line": reply[:80]}).encode())
            return
        bridge._count("forwarded")
        self._send(int(m.group(1)), m.group(2).encode())

    def send_error(self, code, message=None, explain=None) -> None:
        bridge = getattr(self.server, "bridge", None)
        if bridge is not None:
            bridge._count(f"http_{code}")
        super().send_error(code, message, explain)


for _m in FORWARDED_METHODS:
    setattr(_Handler, f"do_{_m}", _Handler._forward)


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def handle_error(self, request, client_address) -> None:
        # A client resetting its connection (scenario 7 does on purpose) is counted, not printed.
        self.bridge._count("connection_errors")  # type: ignore[attr-defined]


class WifiBridgeEmulator:
    def __init__(self, transact: Transact, options: BridgeOptions | None = None) -> None:
        self.options = options or BridgeOptions()
        self.options.validate()
        self._transact_fn = transact
        self._serial_lock = threading.Lock()
        self._counts_lock = threading.Lock()
        self.counts: dict[str, int] = {}
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None

    @property
    def port(self) -> int:
        if self._server is None:
            raise RuntimeError("bridge not started")
        return self._server.server_address[1]

    def start(self) -> "WifiBridgeEmulator":
        server = _Server(("127.0.0.1", self.options.port), _Handler)
        server.bridge = self  # type: ignore[attr-defined]
        self._server = server
        self._thread = threading.Thread(
            target=server.serve_forever,
            kwargs={"poll_interval": 0.05},
            name="bridge-http",
            daemon=True,
        )
        self._thread.start()
        return self

    def close(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def _transact(self, line: str) -> str | None:
        with self._serial_lock:  # one request at a time on the serial link
            return self._transact_fn(line, self.options.reply_timeout_ms / 1000.0)

    def _count(self, key: str) -> None:
        with self._counts_lock:
            self.counts[key] = self.counts.get(key, 0) + 1

    def __enter__(self) -> "WifiBridgeEmulator":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()
