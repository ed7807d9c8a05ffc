"""The spec is consistent, and everything derived from it (C++ header, vectors) is up to date."""

import copy
import subprocess
import sys
from pathlib import Path

import pytest
from rgbd_protocol.spec import Spec, SpecError, load_spec

PROTOCOL = Path(__file__).resolve().parents[2]


def test_spec_validates_and_has_every_required_message():
    spec = load_spec()
    spec.validate()
    names = {m["name"] for m in spec.messages}
    assert {
        "Handshake",
        "HandshakeAck",
        "Frame",
        "FrameRequest",
        "SlamHello",
        "RgbdFrame",
        "PoseUpdate",
        "PoseGraph",
        "FloorMap",
    } <= names


def test_every_numeric_field_states_a_unit_or_is_an_enum_struct_or_flag():
    spec = load_spec()
    owners = [s["fields"] for s in spec.raw["structs"].values()]
    owners += [m["fields"] for m in spec.messages]
    for fields in owners:
        for f in fields:
            t = f["type"]
            if t[0] in "uf" and "unit" not in f:
                pytest.fail(f"field {f['name']} ({t}) has no unit")


def test_reserved_compressed_encodings_are_registered():
    enc = load_spec().enum_values("Encoding")
    assert enc["RAW"] == 0
    assert {"DEPTH_RVL", "DEPTH_ZSTD_DELTA", "RGB_JPEG"} <= set(enc)


def test_schema_hash_ignores_docs_and_encodings_but_not_layout():
    spec = load_spec()
    raw = copy.deepcopy(spec.raw)
    raw["messages"][0]["fields"][0]["doc"] = "reworded"
    raw["encodings"]["DEPTH_LZ4"] = {"code": 4, "status": "reserved", "pixel_formats": ["DEPTH16"]}
    assert Spec(raw).schema_hash == spec.schema_hash
    raw["messages"][0]["fields"][1], raw["messages"][0]["fields"][2] = (
        raw["messages"][0]["fields"][2],
        raw["messages"][0]["fields"][1],
    )
    assert Spec(raw).schema_hash != spec.schema_hash
    raw = copy.deepcopy(spec.raw)
    raw["limits"]["max_string_bytes"]["value"] = 254
    assert Spec(raw).schema_hash != spec.schema_hash


def test_inconsistent_max_body_bytes_is_caught():
    raw = copy.deepcopy(load_spec().raw)
    raw["messages"][0]["max_body_bytes"] += 1
    with pytest.raises(SpecError):
        Spec(raw).validate()


@pytest.mark.parametrize("tool", ["gen_cpp.py", "gen_docs.py", "make_vectors.py"])
def test_generated_files_are_up_to_date(tool):
    r = subprocess.run(
        [sys.executable, str(PROTOCOL / "tools" / tool), "--check"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr


def test_generated_header_carries_the_python_schema_hash():
    header = (PROTOCOL / "cpp/include/rgbdquad/protocol/spec_generated.hpp").read_text()
    assert f"kSchemaHash = 0x{load_spec().schema_hash:016x}ULL" in header
