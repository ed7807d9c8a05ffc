"""Replays a TUM folder to a running slam-server over the SLAM link, as quad-control does under load
(one frame in flight; frames skipped at random to mimic the drops of a busy ground station), and
reports every PoseUpdate that cannot be used and how the connection ended.

    python offboard/slamlink/tools/replay_link.py --port 5700 \
        --data ../shared/data/fr1_xyz_first300 --frames 1500 --max-skip 6 [--spec old_messages.json]

Reproduces SLAM-link resets under a lossy stream (docs/control.md). Frames are read once and kept in
memory; the replay bounces back and forth through the folder. Exit status 0 when the connection
survived every frame, 1 when slam-server closed it.
"""

from __future__ import annotations

import argparse
import random
import socket
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image
from rgbd_protocol import Codec, StreamDecoder
from rgbd_protocol.spec import load_spec
from rgbd_protocol.tum_cameras import TUM_DEPTH_UNITS_PER_M, TUM_FR1


def read_list(path: Path) -> list[tuple[float, str]]:
    out = []
    for line in path.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        t, f = line.split()[:2]
        out.append((float(t), f))
    return out


def load_pairs(folder: Path, limit: int) -> list[tuple[float, bytes, bytes, int, int]]:
    rgbs, depths = read_list(folder / "rgb.txt"), read_list(folder / "depth.txt")
    pairs = []
    for t, f in rgbs[:limit]:
        dt, df = min(depths, key=lambda d: abs(d[0] - t))
        rgb = np.asarray(Image.open(folder / f).convert("RGB"), dtype=np.uint8)
        depth = np.asarray(Image.open(folder / df), dtype=np.uint16).astype("<u2")
        pairs.append((t, rgb.tobytes(), depth.tobytes(), rgb.shape[1], rgb.shape[0]))
    return pairs


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--frames", type=int, default=1000, help="frames to send")
    ap.add_argument("--load", type=int, default=300, help="frames of the folder to use")
    ap.add_argument(
        "--max-skip", type=int, default=1, help="1 = every frame; k = skip up to k-1 at random"
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--session-id", type=lambda s: int(s, 0), default=0)
    ap.add_argument("--spec", type=Path, default=None, help="messages.json of the server's build")
    args = ap.parse_args()
    codec = Codec(load_spec(args.spec) if args.spec else None)
    has_session = any(
        f["name"] == "session_id"
        for m in codec.spec.raw["messages"]
        if m["name"] == "SlamHello"
        for f in m["fields"]
    )
    pairs = load_pairs(args.data, args.load)
    rng = random.Random(args.seed)
    sock = socket.create_connection((args.host, args.port), timeout=60)
    dec = StreamDecoder(codec)
    hello = {
        "protocol_version": codec.spec.version,
        "schema_hash": codec.spec.schema_hash,
        "peer_name": "replay",
    }
    if has_session:
        hello.update(session_id=args.session_id, resumed=False, session_frames=0, refusal="")
    sock.sendall(codec.encode("SlamHello", hello))
    pending: list = []

    def next_message():
        while not pending:
            data = sock.recv(1 << 16)
            if not data:
                return None
            dec.feed(data)
            pending.extend(e for e in dec.drain() if e.kind == "message")
        return pending.pop(0)

    m = next_message()
    print(f"hello: {m.fields if m else 'connection closed'}")
    idx, direction, states = 0, 1, {}
    t0 = time.monotonic()
    for n in range(args.frames):
        step = rng.randint(1, args.max_skip)
        idx += direction * step
        if idx >= len(pairs) or idx < 0:
            direction = -direction
            idx = max(0, min(len(pairs) - 1, idx + 2 * direction * step))
        t, rgb, depth, w, h = pairs[idx]

        def image(fmt, payload, n=n, t=t, w=w, h=h):
            return {
                "sequence": n,
                "capture_timestamp_us": int(t * 1e6),
                "send_timestamp_us": 0,
                "width": w,
                "height": h,
                "pixel_format": fmt,
                "encoding": "RAW",
                "payload": payload,
            }

        sock.sendall(
            codec.encode(
                "RgbdFrame",
                {
                    "pair_sequence": n,
                    # no distortion sent
                    "intrinsics": {**TUM_FR1.intrinsics(), "distortion": [0.0] * 5},
                    "depth_scale_units_per_m": TUM_DEPTH_UNITS_PER_M,
                    # TUM frames: no IMU attitude
                    "attitude": {"valid": False, "q_xyzw": [0.0, 0.0, 0.0, 1.0]},
                    "rgb": image("RGB8", rgb),
                    "depth": image("DEPTH16", depth),
                },
            )
        )
        m = next_message()
        if m is None:
            print(
                f"slam-server closed the connection after {n} frames answered "
                f"(frame {n}, folder index {idx}); "
                f"states so far {states}; {time.monotonic() - t0:.0f} s"
            )
            return 1
        s = m.fields["tracking_state"]
        states[s] = states.get(s, 0) + 1
    print(f"all {args.frames} frames answered; states {states}; {time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
