"""Link proxy: data passes intact and in order, delay and retransmission stalls are applied."""

import socket
import threading
import time

import pytest
from hilrig.link_proxy import LinkImpairment, LinkProxy


@pytest.fixture
def echo_server():
    srv = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve():
        srv.settimeout(0.1)
        while not stop.is_set():
            try:
                c, _ = srv.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return

            def echo(c=c):
                with c:
                    while True:
                        d = c.recv(65536)
                        if not d:
                            return
                        c.sendall(d)

            threading.Thread(target=echo, daemon=True).start()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    yield srv.getsockname()[1]
    stop.set()
    srv.close()
    t.join(timeout=2)


def roundtrip(port, payload: bytes) -> tuple[bytes, float]:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        t0 = time.monotonic()
        s.sendall(payload)
        got = b""
        while len(got) < len(payload):
            got += s.recv(65536)
        return got, time.monotonic() - t0


def test_passes_data_in_order_with_delay(echo_server):
    with LinkProxy(echo_server, LinkImpairment(delay_ms=50)) as p:
        data = bytes(range(256)) * 1000
        got, dt = roundtrip(p.port, data)
    assert got == data
    assert dt >= 0.1  # 50 ms each way


def test_loss_shows_as_retransmission_stalls(echo_server):
    with LinkProxy(echo_server, LinkImpairment(loss=0.5, rto_ms=100, seed=3)) as p:
        for i in range(10):
            got, _ = roundtrip(p.port, b"x%d" % i)
            assert got == b"x%d" % i
        assert 0 < p.stalls < p.chunks


def test_sever_and_restore(echo_server):
    with LinkProxy(echo_server) as p:
        assert roundtrip(p.port, b"a")[0] == b"a"
        p.sever()
        with pytest.raises(OSError):
            socket.create_connection(("127.0.0.1", p.port), timeout=1).close()
        p.restore()
        assert roundtrip(p.port, b"b")[0] == b"b"


def test_validation():
    with pytest.raises(ValueError):
        LinkImpairment(loss=1.0).validate()
