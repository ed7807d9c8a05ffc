"""WiFi-bridge emulator (rgbd_protocol.control_bridge) against a scripted serial side (no
simavr): line format, status mapping, malformed HTTP, timeouts."""

import http.client
import json
import socket

import pytest
from rgbd_protocol.control_bridge import BridgeOptions, WifiBridgeEmulator


class FakeSerial:
    def __init__(self, reply='200 {"err":"ok"}'):
        self.lines = []
        self.reply = reply

    def __call__(self, line, timeout_s):
        self.lines.append(line)
        return self.reply(line) if callable(self.reply) else self.reply


def request(port, method, target, body=None, headers=None):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    c.request(method, target, body=body, headers=headers or {})
    r = c.getresponse()
    data = r.read()
    c.close()
    return r.status, data


def raw_exchange(port, data: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(data)
        s.shutdown(socket.SHUT_WR)
        out = b""
        while True:
            chunk = s.recv(4096)
            if not chunk:
                return out
            out += chunk


def test_forwards_one_line_and_maps_reply_status():
    serial = FakeSerial(lambda line: '409 {"err":"stale_seq","seq":7}')
    with WifiBridgeEmulator(serial) as b:
        status, body = request(b.port, "PUT", "/control?seq=1&arm=0&mac=00", body=b"ignored")
    assert serial.lines == ["PUT /control?seq=1&arm=0&mac=00"]
    assert status == 409 and json.loads(body) == {"err": "stale_seq", "seq": 7}
    assert b.counts == {"forwarded": 1}


def test_keep_alive_serves_several_requests_on_one_connection():
    serial = FakeSerial()
    with WifiBridgeEmulator(serial) as b:
        c = http.client.HTTPConnection("127.0.0.1", b.port, timeout=5)
        for i in range(3):
            c.request("GET", f"/status?i={i}")
            r = c.getresponse()
            assert r.status == 200 and r.read() == b'{"err":"ok"}'
        c.close()
    assert serial.lines == ["GET /status?i=0", "GET /status?i=1", "GET /status?i=2"]


@pytest.mark.parametrize(
    "raw,code",
    [
        (b"GARBAGE\r\n\r\n", b" 400 "),
        (b"PUT /control HTTP/9.9\r\n\r\n", b" 505 "),
        (b"GET /" + b"a" * 70000 + b" HTTP/1.1\r\n\r\n", b" 414 "),
        (b"BREW /pot HTTP/1.1\r\nHost: x\r\n\r\n", b" 501 "),
    ],
)
def test_malformed_http_never_reaches_the_serial_link(raw, code):
    serial = FakeSerial()
    with WifiBridgeEmulator(serial) as b:
        out = raw_exchange(b.port, raw)
    assert out.startswith(b"HTTP/1.") and code in out.split(b"\r\n", 1)[0]
    assert serial.lines == []


def test_oversized_body_refused_before_reading():
    serial = FakeSerial()
    with WifiBridgeEmulator(serial, BridgeOptions(max_body_bytes=10)) as b:
        out = raw_exchange(b.port, b"PUT /control HTTP/1.1\r\nContent-Length: 100000\r\n\r\nxx")
    assert b" 413 " in out.split(b"\r\n", 1)[0] and serial.lines == []


def test_no_reply_is_504_and_bad_reply_is_502():
    with WifiBridgeEmulator(FakeSerial(lambda line: None)) as b:
        assert request(b.port, "GET", "/status")[0] == 504
    with WifiBridgeEmulator(FakeSerial(lambda line: "garbage")) as b:
        assert request(b.port, "GET", "/status")[0] == 502


def test_options_validation():
    with pytest.raises(ValueError):
        WifiBridgeEmulator(FakeSerial(), BridgeOptions(reply_timeout_ms=0))
