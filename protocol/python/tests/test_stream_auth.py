"""Stream authentication (rgbd_protocol.stream_auth) against the golden vectors' signed messages,
and the key-file rules both ends apply (owner-only permissions, 32 hex digits, no zero key)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from rgbd_protocol.codec import Codec, StreamDecoder
from rgbd_protocol.stream_auth import (
    ack_tag,
    handshake_tag,
    load_key_file,
    parse_key,
    tags_equal,
    write_key_file,
)

VECTORS = Path(__file__).resolve().parents[2] / "vectors"
CODEC = Codec()


def _messages(name: str):
    dec = StreamDecoder(CODEC)
    dec.feed((VECTORS / f"{name}.bin").read_bytes())
    return [(e.name, e.fields) for e in dec.drain() if e.kind == "message"]


def test_vector_tags_verify_and_forged_ones_do_not():
    manifest = json.loads((VECTORS / "manifest.json").read_text())
    auth = manifest["stream_auth"]
    key, rn, sn = (bytes.fromhex(auth[k]) for k in ("key", "receiver_nonce", "sender_nonce"))
    other_key = key[:-1] + bytes([key[-1] ^ 0x80])
    counts = {"signed": 0, "forged": 0}
    for v in manifest["vectors"]:
        for name, fields in _messages(v["name"]):
            if name == "Handshake":
                tag = lambda k, n=rn, fields=fields: handshake_tag(CODEC, k, n, fields)  # noqa: E731
            elif name == "HandshakeAck":
                tag = lambda k, n=rn, fields=fields: ack_tag(CODEC, k, n, sn, fields)  # noqa: E731
            else:
                continue
            ok = tags_equal(fields["mac"], tag(key))
            assert ok == (v["name"] not in auth["forged"]), v["name"]
            assert not tags_equal(fields["mac"], tag(other_key)), v["name"]
            assert not tags_equal(fields["mac"], tag(key, bytes(16))), v["name"]
            counts["signed" if ok else "forged"] += 1
    assert counts["signed"] >= 8 and counts["forged"] == 2


def test_key_file_must_be_owner_only(tmp_path):
    path = tmp_path / "stream.key"
    key = write_key_file(path)
    assert load_key_file(path) == key
    os.chmod(path, 0o644)
    with pytest.raises(PermissionError, match="chmod 600"):
        load_key_file(path)


@pytest.mark.parametrize("text", ["", "abc", "0" * 32, "zz" * 16, "00" * 17])
def test_bad_keys_are_refused(text):
    with pytest.raises(ValueError):
        parse_key(text)
