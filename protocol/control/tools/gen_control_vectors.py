#!/usr/bin/env python3
"""Writes protocol/control/vectors/control_vectors.json: the golden vectors of the control link.

Every expectation below (status codes, states, pulse widths, failsafe throttle values) is written
out by hand from control_spec.json, firmware/core/limits.h and docs/failsafe.md; only the request
lines and their MACs are produced with rgbd_protocol.control. The firmware core (GoogleTest), the
C++ ground-station codec and the Python codec all replay this file.

Usage: gen_control_vectors.py [--check]   (--check: exit 1 if the committed file is out of date)
"""

import argparse
import json
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "python"))
from rgbd_protocol import control  # noqa: E402  (path set up above: run as a script)

OUT = HERE.parent / "vectors" / "control_vectors.json"
KEY = bytes(range(16))  # the SipHash paper's key 00..0f
OTHER_KEY = bytes(range(16, 32))  # a different craft's key
SAFE = [1500, 1500, 1000, 1500]  # disarmed outputs: neutral, throttle low


def req(seq, arm=1, roll=1500, pitch=1500, thr=1000, yaw=1500, key=KEY):
    return control.build_control_request(key, seq, bool(arm), roll, pitch, thr, yaw)


def raw_req(seq, arm=1, roll=1500, pitch=1500, thr=1000, yaw=1500, key=KEY):
    """A correctly signed line whose values may be out of range (the builder refuses those)."""
    signed = f"PUT /control?seq={seq}&arm={arm}&roll={roll}&pitch={pitch}&thr={thr}&yaw={yaw}"
    return signed + "&mac=" + control.siphash24(key, signed.encode()).hex()


def step(t_ms, send, status, state, out_us=None, **extra):
    s = {"t_ms": t_ms, "send": send, "status": status, "state": state}
    if out_us is not None:
        s["out_us"] = out_us
    s.update(extra)
    return s


def line(text):
    return text + "\n"


def siphash_vectors():
    # Reference vectors (SipHash paper / reference vectors.h): key 00..0f, message 00..n-1.
    known = {
        0: "310e0edd47db6f72",
        1: "fd67dc93c539f874",
        15: "e545be4961ca29a1",
        63: "724506eb4c328a95",
    }
    out = []
    for n in range(64):
        tag = control.siphash24(KEY, bytes(range(n))).hex()
        if n in known and known[n] != tag:
            raise SystemExit(f"SipHash implementation disagrees with reference vector {n}")
        out.append({"key_hex": KEY.hex(), "msg_hex": bytes(range(n)).hex(), "tag_hex": tag})
    return out


def malformed_lines():
    good = req(5)
    base = good[: good.index("&mac=")]
    mac = good[good.index("&mac=") + 5 :]
    cases = [
        ("empty", "", 400),
        ("garbage", "hello", 400),
        ("lowercase_method", good.replace("PUT", "put", 1), 400),
        ("unknown_method", good.replace("PUT", "POST", 1), 405),
        ("get_control", good.replace("PUT", "GET", 1), 405),
        ("put_status", "PUT /status", 405),
        ("status_with_query", "GET /status?x=1", 400),
        ("unknown_route", good.replace("/control", "/motors", 1), 404),
        ("missing_field", base.replace("&yaw=1500", "") + "&mac=" + mac, 400),
        (
            "reordered_fields",
            base.replace("roll=1500&pitch=1500", "pitch=1500&roll=1500") + "&mac=" + mac,
            400,
        ),
        ("duplicate_field", base + "&yaw=1500&mac=" + mac, 400),
        ("extra_field", base + "&mode=1&mac=" + mac, 400),
        ("leading_zero", base.replace("roll=1500", "roll=01500") + "&mac=" + mac, 400),
        ("negative", base.replace("roll=1500", "roll=-1500") + "&mac=" + mac, 400),
        ("non_digit", base.replace("roll=1500", "roll=15a0") + "&mac=" + mac, 400),
        ("empty_value", base.replace("roll=1500", "roll=") + "&mac=" + mac, 400),
        ("eleven_digits", base.replace("seq=5", "seq=10000000000") + "&mac=" + mac, 400),
        (
            "uppercase_mac",
            base + "&mac=" + mac.upper().replace("X", "x"),
            400 if mac.upper() != mac else 401,
        ),
        ("short_mac", base + "&mac=" + mac[:15], 400),
        ("long_mac", base + "&mac=" + mac + "0", 400),
        ("missing_mac", base, 400),
        ("trailing_space", good + " ", 400),
        ("tab_byte", good.replace("&arm", "\t&arm"), 400),
        ("control_byte", good[:20] + "\u0001" + good[21:], 400),
        ("high_byte", good[:20] + "\u00ff" + good[21:], 400),
        ("truncated", good[: len(good) // 2], 400),
    ]
    return [{"name": n, "line": text, "status": st} for n, text, st in cases]


def scenarios():
    sc = []
    # Arming, clamping, disarm.
    sc.append(
        {
            "name": "arm_clamp_disarm",
            "key": "test",
            "steps": [
                step(0, "", None, "disarmed", SAFE),
                step(
                    10,
                    line(req(1, arm=1, thr=1000, yaw=2000)),
                    200,
                    "armed",
                    [1500, 1500, 1000, 2000],
                    clamped=0,
                    note="arming gesture: throttle low, yaw full right is allowed on the ground",
                ),
                step(
                    20,
                    line(req(2, arm=1, roll=2000, pitch=1000, thr=2000, yaw=2000)),
                    200,
                    "armed",
                    [1750, 1250, 1750, 1750],
                    clamped=15,
                ),
                step(
                    30,
                    line(req(3, arm=1, roll=1600, pitch=1400, thr=1500, yaw=1450)),
                    200,
                    "armed",
                    [1600, 1400, 1500, 1450],
                    clamped=0,
                ),
                step(
                    40,
                    line(req(4, arm=0, roll=1600, pitch=1400, thr=1500, yaw=1450)),
                    200,
                    "disarmed",
                    SAFE,
                ),
            ],
        }
    )
    # Arming refused with throttle high; disarmed commands keep outputs safe.
    sc.append(
        {
            "name": "arm_refused_throttle_high",
            "key": "test",
            "steps": [
                step(0, line(req(1, arm=1, thr=1101)), 403, "disarmed", SAFE),
                step(10, line(req(2, arm=0, thr=1800, roll=1900)), 200, "disarmed", SAFE),
                step(20, line(req(3, arm=1, thr=1100)), 200, "armed", [1500, 1500, 1100, 1500]),
            ],
        }
    )
    # Failsafe timeline from a 1500 us hover (docs/failsafe.md, firmware/core/limits.h).
    t0 = 100
    FS = [1500, 1500, 950, 1500]
    fs = [
        step(0, line(req(1, arm=1, thr=1000)), 200, "armed"),
        step(
            t0,
            line(req(2, arm=1, roll=1600, pitch=1450, thr=1500, yaw=1550)),
            200,
            "armed",
            [1600, 1450, 1500, 1550],
        ),
        step(t0 + 249, "", None, "armed", [1600, 1450, 1500, 1550]),
        step(
            t0 + 250,
            "",
            None,
            "failsafe",
            FS,
            note="neutral sticks and throttle below FS_THR_VALUE at once: APM LAND takes over",
        ),
        step(t0 + 250 + 60, "", None, "failsafe", FS),
        step(t0 + 250 + 60000, "", None, "failsafe", FS),
        step(
            t0 + 250 + 60010,
            line(req(3, arm=1, thr=1000)),
            403,
            "failsafe",
            [1500, 1500, 950, 1500],
            note="leaving failsafe needs disarm then a fresh arm",
        ),
        step(t0 + 250 + 60020, line(req(4, arm=0, thr=1000)), 200, "disarmed", SAFE),
        step(
            t0 + 250 + 60030, line(req(5, arm=1, thr=1000)), 200, "armed", [1500, 1500, 1000, 1500]
        ),
    ]
    sc.append({"name": "failsafe_timeline", "key": "test", "steps": fs})
    # Rejected commands do not feed the failsafe timer.
    sc.append(
        {
            "name": "rejected_do_not_feed_timer",
            "key": "test",
            "steps": [
                step(0, line(req(1, arm=1, thr=1000)), 200, "armed"),
                step(10, line(req(2, arm=1, thr=1400)), 200, "armed", [1500, 1500, 1400, 1500]),
                step(
                    100, line(req(2, arm=1, thr=1400)), 409, "armed", note="replay of the same line"
                ),
                step(
                    150,
                    line(req(1, arm=1, thr=1600)),
                    409,
                    "armed",
                    [1500, 1500, 1400, 1500],
                    note="older seq",
                ),
                step(
                    200,
                    line(req(3, arm=1, thr=1600, key=OTHER_KEY)),
                    401,
                    "armed",
                    [1500, 1500, 1400, 1500],
                    note="another craft's key",
                ),
                step(
                    230,
                    line(req(3, arm=1, thr=1400).replace("thr=1400", "thr=1700")),
                    401,
                    "armed",
                    [1500, 1500, 1400, 1500],
                    note="forged: field changed, MAC kept",
                ),
                step(
                    240, line(raw_req(3, arm=1, roll=2001)), 422, "armed", [1500, 1500, 1400, 1500]
                ),
                step(259, "", None, "armed", [1500, 1500, 1400, 1500]),
                step(260, "", None, "failsafe", [1500, 1500, 950, 1500]),
            ],
        }
    )
    # Range errors (valid MAC) and overflowing seq.
    bad_seq = raw_req(4294967296)
    arm2 = raw_req(7, arm=2)
    sc.append(
        {
            "name": "out_of_range",
            "key": "test",
            "steps": [
                step(0, line(raw_req(1, arm=1, roll=999)), 422, "disarmed", SAFE),
                step(1, line(raw_req(2, arm=1, thr=2001)), 422, "disarmed", SAFE),
                step(2, line(bad_seq), 422, "disarmed", SAFE),
                step(3, line(arm2), 422, "disarmed", SAFE),
                step(4, line(raw_req(8, arm=1, yaw=0)), 422, "disarmed", SAFE),
                step(5, line(req(9, arm=1)), 200, "armed", [1500, 1500, 1000, 1500]),
            ],
        }
    )
    # Framing: over-long, stalled (truncated in transit), CRLF, status route.
    sc.append(
        {
            "name": "framing",
            "key": "test",
            "steps": [
                step(0, "X" * 300 + "\n", 414, "disarmed", SAFE),
                step(
                    1,
                    "Y" * 200,
                    414,
                    "disarmed",
                    SAFE,
                    note="answered on the first byte past 128, before any newline",
                ),
                step(5, "Y" * 50 + "\n", None, "disarmed", note="rest of it discarded silently"),
                step(10, "PUT /control?seq=1&ar", None, "disarmed"),
                step(109, "", None, "disarmed"),
                step(110, "", 408, "disarmed"),
                step(120, req(1, arm=1) + "\r\n", 200, "armed", [1500, 1500, 1000, 1500]),
                step(130, "GET /status\n", 200, "armed"),
                step(369, "GET /status\n", 200, "armed", note="status reads do not feed the timer"),
                step(370, "", None, "failsafe"),
                step(380, "GET /status\n", 200, "failsafe"),
            ],
        }
    )
    # No key provisioned.
    sc.append(
        {
            "name": "no_key",
            "key": None,
            "steps": [
                step(0, line(req(1, arm=1)), 503, "disarmed", SAFE),
                step(10, "GET /status\n", 200, "disarmed", SAFE),
            ],
        }
    )
    return sc


def replies():
    return [
        {
            "line": '200 {"ver":2,"err":"ok","fw":"0.1.0","state":"armed","seq":2,'
            '"out_us":[1600,1450,1500,1550],'
            '"clamped":0,"att_mrad":[12,-34,3141],"att_age_ms":20,'
            '"imu_raw":[1,-2,-1000,30,-40,5],"imu_age_ms":21}\n',
            "valid": True,
            "fields": {
                "status": 200,
                "ver": 2,
                "err": "ok",
                "fw": "0.1.0",
                "state": "armed",
                "seq": 2,
                "out_us": [1600, 1450, 1500, 1550],
                "clamped": 0,
                "att_mrad": [12, -34, 3141],
                "att_age_ms": 20,
                "imu_raw": [1, -2, -1000, 30, -40, 5],
                "imu_age_ms": 21,
            },
        },
        {
            "line": '409 {"ver":2,"err":"stale_seq","fw":"0.1.0","state":"failsafe",'
            '"seq":4294967295,'
            '"out_us":[1500,1500,950,1500],"clamped":15,"att_mrad":[0,0,0],"att_age_ms":null,'
            '"imu_raw":[0,0,0,0,0,0],"imu_age_ms":null}\n',
            "valid": True,
            "fields": {
                "status": 409,
                "ver": 2,
                "err": "stale_seq",
                "fw": "0.1.0",
                "state": "failsafe",
                "seq": 4294967295,
                "out_us": [1500, 1500, 950, 1500],
                "clamped": 15,
                "att_mrad": [0, 0, 0],
                "att_age_ms": None,
                "imu_raw": [0, 0, 0, 0, 0, 0],
                "imu_age_ms": None,
            },
        },
        # Another control-link version: refused by name, whatever follows the version.
        {
            "line": '200 {"ver":3,"err":"ok","fw":"0.1.0","state":"armed","seq":2,'
            '"out_us":[1,2,3,4],'
            '"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,"imu_raw":[0,0,0,0,0,0],'
            '"imu_age_ms":null}\n',
            "valid": False,
            "error_mentions": "version",
        },
        {"line": '200 {"ver":1,"new_layout":true}\n', "valid": False, "error_mentions": "version"},
        # A version-1 firmware's reply (no "ver" key): refused.
        {
            "line": '200 {"err":"ok","fw":"0.1.0","state":"armed","seq":2,"out_us":[1,2,3,4],'
            '"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,"imu_raw":[0,0,0,0,0,0],'
            '"imu_age_ms":null}\n',
            "valid": False,
        },
        {"line": "", "valid": False},
        {"line": "200", "valid": False},
        {"line": '200 {"ver":2,"err":"ok"}\n', "valid": False},
        {
            "line": '200 {"ver":2,"err":"bad_mac","fw":"0.1.0","state":"armed","seq":2,'
            '"out_us":[1,2,3,4],'
            '"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,"imu_raw":[0,0,0,0,0,0],'
            '"imu_age_ms":null}\n',
            "valid": False,
        },
        {
            "line": '200 {"ver":2,"err":"ok","fw":"0.1.0","state":"flying","seq":2,'
            '"out_us":[1,2,3,4],'
            '"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,"imu_raw":[0,0,0,0,0,0],'
            '"imu_age_ms":null}\n',
            "valid": False,
        },
        {
            "line": '200 {"ver":2,"err":"ok","fw":"0.1.0","state":"armed","seq":2,"out_us":[1,2,3],'
            '"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,"imu_raw":[0,0,0,0,0,0],'
            '"imu_age_ms":null}\n',
            "valid": False,
        },
        {
            "line": '200 {"ver":2,"err":"ok","fw":"0.1.0","state":"armed","seq":2,'
            '"out_us":[1,2,3,4],'
            '"clamped":0,"att_mrad":[0,0,0],"att_age_ms":null,"imu_raw":[0,0,0,0,0,0],'
            '"imu_age_ms":null',
            "valid": False,
        },
    ]


def requests():
    cases = [
        dict(seq=1, arm=1, roll=1500, pitch=1500, thr=1000, yaw=1500),
        dict(seq=2, arm=0, roll=1000, pitch=2000, thr=1000, yaw=2000),
        dict(seq=4294967295, arm=1, roll=2000, pitch=2000, thr=2000, yaw=2000),
        dict(seq=123456, arm=1, roll=1234, pitch=1765, thr=1432, yaw=1501),
    ]
    out = []
    for c in cases:
        out.append(
            {
                **c,
                "key_hex": KEY.hex(),
                "line": req(c["seq"], c["arm"], c["roll"], c["pitch"], c["thr"], c["yaw"]),
            }
        )
    invalid = [
        dict(seq=0, arm=1, roll=1500, pitch=1500, thr=1000, yaw=1500),
        dict(seq=1, arm=1, roll=999, pitch=1500, thr=1000, yaw=1500),
        dict(seq=1, arm=1, roll=1500, pitch=1500, thr=2001, yaw=1500),
    ]
    return out, invalid


def build():
    valid, invalid = requests()
    return {
        "about": "Golden vectors of the control link, generated by protocol/control/tools/"
        "gen_control_vectors.py; expectations hand-written from control_spec.json and "
        "docs/failsafe.md. Scenario steps: at t_ms feed 'send' byte by byte into the "
        "firmware's line assembler, then poll it and run the failsafe update; 'status' is "
        "the reply produced by that step (null = none), 'state'/'out_us' hold after it.",
        "key_hex": KEY.hex(),
        "siphash": siphash_vectors(),
        "requests": valid,
        "invalid_requests": invalid,
        "malformed": malformed_lines(),
        "scenarios": scenarios(),
        "replies": replies(),
    }


def main():
    ap = argparse.ArgumentParser(description="write or check the control-link golden vectors")
    ap.add_argument("--check", action="store_true", help="fail if the committed file differs")
    args = ap.parse_args()
    text = json.dumps(build(), indent=1) + "\n"
    if args.check:
        if not OUT.is_file() or OUT.read_text() != text:
            print(f"{OUT} is out of date: run {pathlib.Path(__file__).name}")
            return 1
        return 0
    OUT.write_text(text)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
