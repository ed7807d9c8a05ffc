"""Authentication of the RGB-D stream (spec protocol.stream_auth; docs/protocol.md "Stream
authentication"), the Python twin of protocol/cpp/include/rgbdquad/protocol/stream_auth.hpp.

    receiver -> sender   StreamChallenge{receiver_nonce}
    sender -> receiver   Handshake{..., sender_nonce, mac = handshake_tag(key, receiver_nonce, hs)}
    receiver -> sender   HandshakeAck{accepted, reason, mac = ack_tag(key, rn, sn, ack)}

Tags are SipHash-2-4 (the control link's MAC, rgbd_protocol.control.siphash24) over the label, the
nonce(s) and the message body with ``mac`` set to zeros.
"""

from __future__ import annotations

import hmac
import os
import stat
from pathlib import Path

from .codec import Codec
from .control import siphash24


def _auth(codec: Codec) -> dict:
    return codec.spec.raw["protocol"]["stream_auth"]


def _zero_mac(codec: Codec, fields: dict) -> dict:
    return dict(fields, mac=[0] * _auth(codec)["tag_bytes"])


def handshake_tag(codec: Codec, key: bytes, receiver_nonce: bytes, handshake: dict) -> list[int]:
    """The Handshake's mac (a list of ints, as the codec's u8[N] fields) answering
    receiver_nonce."""
    body = codec.encode_body("Handshake", _zero_mac(codec, handshake))
    msg = _auth(codec)["handshake_label"].encode("ascii") + bytes(receiver_nonce) + body
    return list(siphash24(key, msg))


def ack_tag(
    codec: Codec, key: bytes, receiver_nonce: bytes, sender_nonce: bytes, ack: dict
) -> list[int]:
    """The HandshakeAck's mac on the connection with these nonces."""
    body = codec.encode_body("HandshakeAck", _zero_mac(codec, ack))
    msg = (
        _auth(codec)["ack_label"].encode("ascii")
        + bytes(receiver_nonce)
        + bytes(sender_nonce)
        + body
    )
    return list(siphash24(key, msg))


def tags_equal(a, b) -> bool:
    return hmac.compare_digest(bytes(a), bytes(b))


def parse_key(text: str) -> bytes:
    """32 hex digits (whitespace around ignored) -> 16 bytes; ValueError with the reason."""
    hexdigits = text.strip()
    if len(hexdigits) != 32:
        raise ValueError(f"a stream key is 32 hex digits, found {len(hexdigits)} characters")
    key = bytes.fromhex(hexdigits)
    if key == bytes(16):
        raise ValueError("the stream key is all zeros (an unfilled template)")
    return key


def load_key_file(path: Path | str) -> bytes:
    """Reads a key file as the C++ side does: owner-only permissions (0600/0400) are required."""
    st = os.stat(path)
    if st.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise PermissionError(
            f"stream key file {path} is accessible by group or others "
            f"(mode {stat.S_IMODE(st.st_mode):04o}); chmod 600 {path}"
        )
    return parse_key(Path(path).read_text())


def write_key_file(path: Path | str, key: bytes | None = None) -> bytes:
    """Creates a key file (mode 0600) for tests and HIL rigs; a random key unless one is given."""
    key = os.urandom(16) if key is None else key
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(key.hex() + "\n")
    os.chmod(path, 0o600)
    return key
