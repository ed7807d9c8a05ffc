"""Python ground-station codec of the control link (rgbd_protocol.control) against the golden
vectors, plus the consistency of the spec with the firmware's constants."""

import json
import pathlib
import re
import subprocess
import sys

import pytest
from fw_limits import FW_LIMITS
from rgbd_protocol import control

HERE = pathlib.Path(__file__).resolve().parent
VECTORS = json.loads((HERE.parent / "vectors" / "control_vectors.json").read_text())
REPO = HERE.parents[2]
KEY = bytes.fromhex(VECTORS["key_hex"])


@pytest.mark.parametrize("v", VECTORS["siphash"], ids=lambda v: f"len{len(v['msg_hex']) // 2}")
def test_siphash_vectors(v):
    assert (
        control.siphash24(bytes.fromhex(v["key_hex"]), bytes.fromhex(v["msg_hex"])).hex()
        == v["tag_hex"]
    )


def test_siphash_reference_vectors_from_the_paper():
    # Independent of the generated file: the SipHash reference implementation's vectors.
    assert control.siphash24(KEY, b"").hex() == "310e0edd47db6f72"
    assert control.siphash24(KEY, bytes(range(15))).hex() == "e545be4961ca29a1"
    assert control.siphash24(KEY, bytes(range(63))).hex() == "724506eb4c328a95"


@pytest.mark.parametrize("r", VECTORS["requests"], ids=lambda r: f"seq{r['seq']}")
def test_builder_reproduces_golden_requests(r):
    line = control.build_control_request(
        bytes.fromhex(r["key_hex"]),
        r["seq"],
        bool(r["arm"]),
        r["roll"],
        r["pitch"],
        r["thr"],
        r["yaw"],
    )
    assert line == r["line"]
    assert len(line) <= control.MAX_REQUEST_BYTES


@pytest.mark.parametrize("r", VECTORS["invalid_requests"])
def test_builder_refuses_out_of_range_values(r):
    with pytest.raises(ValueError):
        control.build_control_request(
            KEY, r["seq"], bool(r["arm"]), r["roll"], r["pitch"], r["thr"], r["yaw"]
        )


def test_builder_refuses_wrong_key_length_and_bool_as_int():
    with pytest.raises(ValueError):
        control.build_control_request(KEY[:15], 1, True, 1500, 1500, 1000, 1500)
    with pytest.raises(ValueError):
        control.build_control_request(KEY, True, True, 1500, 1500, 1000, 1500)


def test_mac_covers_every_field():
    base = control.build_control_request(KEY, 7, True, 1500, 1500, 1000, 1500)
    variants = [
        control.build_control_request(KEY, 8, True, 1500, 1500, 1000, 1500),
        control.build_control_request(KEY, 7, False, 1500, 1500, 1000, 1500),
        control.build_control_request(KEY, 7, True, 1501, 1500, 1000, 1500),
        control.build_control_request(KEY, 7, True, 1500, 1501, 1000, 1500),
        control.build_control_request(KEY, 7, True, 1500, 1500, 1001, 1500),
        control.build_control_request(KEY, 7, True, 1500, 1500, 1000, 1501),
    ]
    macs = {line.rsplit("&mac=", 1)[1] for line in [base] + variants}
    assert len(macs) == 7


@pytest.mark.parametrize("rep", VECTORS["replies"], ids=lambda r: r["line"][:20] or "empty")
def test_reply_parser_on_golden_replies(rep):
    if rep["valid"]:
        parsed = control.parse_reply(rep["line"])
        for k, v in rep["fields"].items():
            got = getattr(parsed, k)
            assert (list(got) if isinstance(got, tuple) else got) == v, k
    else:
        with pytest.raises(ValueError, match=rep.get("error_mentions")):
            control.parse_reply(rep["line"])


def test_sequence_counter_is_strictly_increasing_and_resumable():
    c = control.SequenceCounter()
    assert [c.next() for _ in range(3)] == [1, 2, 3]
    c = control.SequenceCounter(start_after=41)
    assert c.next() == 42
    c = control.SequenceCounter(start_after=2**32 - 2)
    assert c.next() == 2**32 - 1
    with pytest.raises(OverflowError):
        c.next()


def test_golden_vectors_are_up_to_date():
    gen = HERE.parent / "tools" / "gen_control_vectors.py"
    proc = subprocess.run(
        [sys.executable, str(gen), "--check"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_generated_constants_and_types_are_up_to_date():
    gen = HERE.parent / "tools" / "gen_control.py"
    proc = subprocess.run(
        [sys.executable, str(gen), "--check"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_spec_ranges_and_limits_agree_with_the_firmware():
    # The firmware takes the protocol range and the request bound from the generated header; its
    # own hard limits (read from firmware/core/limits.h) must lie inside the protocol range.
    lim = FW_LIMITS
    assert (lim["kCommandMinUs"], lim["kCommandMaxUs"]) == control.RANGES["roll"]
    for ch in ("roll", "pitch", "thr", "yaw"):
        assert control.RANGES[ch] == (control.CHANNEL_MIN_US, control.CHANNEL_MAX_US)
    for name in ("Roll", "Pitch", "Yaw", "Throttle"):
        assert (
            control.CHANNEL_MIN_US
            <= lim[f"k{name}MinUs"]
            < lim[f"k{name}MaxUs"]
            <= control.CHANNEL_MAX_US
        )
    assert control.MAX_REQUEST_BYTES == lim["kMaxRequestBytes"]
    # The firmware has no status table of its own any more: firmware/core/status.h aliases the
    # generated one.
    status_h = (REPO / "firmware" / "core" / "status.h").read_text()
    assert "rgbd_control::Status" in status_h and not re.search(r"k\w+ = \d+,", status_h)
    board_h = (REPO / "firmware" / "avr" / "board.h").read_text()
    assert "kBridgeBaud = rgbd_control::kBridgeBaud" in board_h


def test_longest_reply_fits_the_spec_bound():
    # The firmware's worst-case reply (firmware test Reply.WorstCaseFitsBufferAndCarriesImu) is
    # 257 bytes; the spec promises max_bytes, the ground station sizes buffers from it.
    assert control.MAX_REPLY_BYTES >= 257
