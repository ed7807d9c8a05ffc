"""quad-control's MCAP recording end to end: the real quad-control (TUM replay, in-process SLAM, the
firmware double behind the HIL WiFi-bridge emulator: the `firmware` fixture of conftest.py, all on
127.0.0.1) records with --record; the file is read back by the Python `mcap` reader
(offboard/recorder/flight_recording; the writer is offboard/recorder, docs/recording.md).

  * a flight stopped with SIGTERM: a complete file (summary, CRCs), every channel of
    docs/recording.md present, images of every frame decodable, the recorded depth (RVL from the
    C++ encoder) decoded by flight_recording.depth equal to the dataset's depth image bit for bit;
  * a short recording (the 30-frame excerpt played once, slowly enough for SLAM to see most frames)
    replayed through SLAM by flight_recording.replay agrees with the poses flown within 30 mm;
  * SIGKILL mid-flight (by PID): the streaming read recovers the flight up to about its last second;
    the recovered fraction is printed;
  * a full disk (RLIMIT_FSIZE on quad-control): recording stops with the cause in /api/state and
    one log line, while frames and commands go on.
Processes are stopped by PID; nothing asserts on wall time beyond generous deadlines.
"""

from __future__ import annotations

import base64
import io
import json
import os
import resource
import signal
import time
import urllib.request
from pathlib import Path

import numpy as np
from dashboard_fixtures import REPO, QuadControl, write_config
from flight_recording.depth import decode as decode_depth
from flight_recording.reader import read, read_complete
from flight_recording.replay import run as replay

DEADLINE_S = 90.0  # the shared 2-core machine may run SLAM at ~1 pose/s
DATASET = REPO / "tests/data/fr1_xyz_first30"
# Replay vs flight: both are this project's ORB + local-map SLAM on the same recorded frames, so
# they differ only by the frames the real-time flight dropped and JPEG re-encoding of the replay
# source; 30 mm is make demo's SLAM ATE target (docs/hil.md): agreement well inside what a flight
# is judged by.
REPLAY_TOLERANCE_M = 0.030
# The excerpt played at a quarter of its speed (7.5 fps) so that in-flight SLAM, ~1 pose/s on a
# loaded machine at worst, still gives several poses to compare.
SLOW_REPLAY_SPEED = 0.25
FLIGHT_S = 12.0  # long enough that the last second is a small part of it


def api_state(url: str) -> dict:
    with urllib.request.urlopen(url + "api/state", timeout=5) as r:
        return json.load(r)


def api_post(url: str, path: str, body: dict) -> dict:
    req = urllib.request.Request(
        url + path,
        data=json.dumps(body).encode(),
        method="POST",
        headers={"Content-Type": "application/json"},
    )
    with urllib.request.urlopen(req, timeout=5) as r:
        return json.load(r)


def wait_for(predicate, what: str, timeout_s: float = DEADLINE_S):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got = predicate()
        if got:
            return got
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


def start(
    binary: Path,
    tmp: Path,
    bridge_port: int,
    record_dir: Path,
    preexec_fn=None,
    image_every: int | None = None,
    stream: dict | None = None,
) -> QuadControl:
    cfg = write_config(tmp, bridge_port)
    doc = json.loads(cfg.read_text())
    doc["recording"] = {} if image_every is None else {"image_every_n_frames": image_every}
    doc["stream"].update(stream or {})
    cfg.write_text(json.dumps(doc))
    qc = QuadControl(
        binary,
        ["--config", str(cfg), "--port", "0", "--record", str(record_dir)],
        preexec_fn=preexec_fn,
    )
    wait_for(lambda: api_state(qc.url)["recording"]["messages"] >= 1, "the first recorded messages")
    return qc


def fly(qc: QuadControl, seconds: float) -> dict:
    # Arm only once commands (and with them the recorder's state events) are flowing: arming in the
    # first milliseconds would record " -> armed" with no disarmed state before it.
    wait_for(
        lambda: api_state(qc.url)["recording"]["messages"] >= 100,
        "recorded telemetry before arming",
    )
    api_post(qc.url, "api/command", {"command": "arm"})
    # The arm gesture ends when the firmware reports armed; on a loaded machine that can take longer
    # than a fixed sleep, and the recording is then checked for an arming it never saw.
    wait_for(lambda: api_state(qc.url)["state"] == "armed", "armed (gesture finished)")
    time.sleep(seconds)
    return api_state(qc.url)


def one_file(d: Path) -> Path:
    files = sorted(d.glob("*.mcap"))
    assert len(files) == 1, files
    return files[0]


def test_sigterm_leaves_a_complete_recording_with_every_channel(binary, firmware, tmp_path):
    _double, b = firmware
    qc = start(binary, tmp_path, b.port, tmp_path / "rec")
    try:
        fly(qc, FLIGHT_S)
    finally:
        qc.stop()
    rec = read_complete(one_file(tmp_path / "rec"))
    counts = rec.counts()
    print("channels and message counts:", json.dumps(counts, sort_keys=True))
    for topic in (
        "/stream/frame",
        "/camera/rgb/compressed",
        "/camera/depth/compressed",
        "/camera/depth/raw",
        "/camera/calibration",
        "/control/command",
        "/firmware/reply",
        "/events",
        "/log",
        "/recorder/stats",
        "/slam/tracking",
        "/latency",
        "/control/setpoint",
    ):
        assert counts.get(topic, 0) > 0, f"{topic} missing: {counts}"
    # Frames: one /stream/frame per frame received; images of every frame (the default).
    frames = rec.topic("/stream/frame")
    assert [m.data["sequence"] for m in frames] == sorted(m.data["sequence"] for m in frames)
    # On a loaded machine the writer may drop images (counted), never the frames' telemetry.
    # The TUM replay comes decoded: these frames are JPEG + RVL encoded by the writer thread (the
    # live stream's are stored as they are); a starved writer drops images, counted in the last
    # /recorder/stats (written after the stop's drain).
    images = counts["/camera/rgb/compressed"]
    last = rec.topic("/recorder/stats")[-1].data
    print(
        f"images {images} of {len(frames)} frames, {last['images_dropped']} dropped, encode "
        f"{last['encode_ms_per_frame']:.2f} ms per frame, load {os.getloadavg()[0]:.1f}"
    )
    assert images + last["images_dropped"] == len(frames), (images, last, len(frames))
    assert images >= 1
    assert counts["/camera/depth/compressed"] == images
    # The depth preview for Foxglove: every 30th recorded frame, with the calibration.
    assert abs(counts["/camera/depth/raw"] - images / 30) <= 2, counts
    from PIL import Image

    rgb = rec.topic("/camera/rgb/compressed")[0].data
    assert rgb["format"] == "jpeg" and rgb["frame_id"] == "camera"
    assert Image.open(io.BytesIO(base64.b64decode(rgb["data"]))).size == (640, 480)
    depth = rec.topic("/camera/depth/raw")[0].data
    assert depth["encoding"] == "16UC1" and depth["step"] == 2 * depth["width"]
    assert len(base64.b64decode(depth["data"])) == depth["height"] * depth["step"]
    # The TUM replay comes decoded, so the recorder RVL-encoded the depth (C++); the Python decoder
    # must give the dataset's 16-bit PNG back bit for bit (the replay source keeps the PNG's units).
    dataset = {np.asarray(Image.open(p)).tobytes() for p in (DATASET / "depth").glob("*.png")}
    compressed = rec.topic("/camera/depth/compressed")
    assert {m.data["encoding"] for m in compressed} == {"rvl"}
    for m in compressed[:: max(1, len(compressed) // 10)]:
        d = m.data
        pixels = decode_depth(d["encoding"], base64.b64decode(d["data"]), d["width"], d["height"])
        assert pixels.tobytes() in dataset, f"depth at {d['timestamp']} is not a dataset image"
    # Commands and the state machine.
    assert any("disarmed -> armed" in m.data["text"] for m in rec.topic("/events"))
    armed = [m.data for m in rec.topic("/control/command") if m.data["armed"]]
    assert armed and all(1000 <= m["pwm_us"]["throttle"] <= 2000 for m in armed)
    assert all(m.data["state"] in ("disarmed", "armed") for m in rec.topic("/firmware/reply"))


def test_sigkill_leaves_the_flight_readable_up_to_about_its_last_second(binary, firmware, tmp_path):
    _double, b = firmware
    # Images at 1 Hz: this test is about what a kill leaves, so the writer's load is kept small
    # (at 5 Hz a machine at load ~15 starved it into dropping events, docs/recording.md).
    qc = start(binary, tmp_path, b.port, tmp_path / "rec", image_every=30)
    state = fly(qc, FLIGHT_S)
    frames_before = state["stream"]["frames"]
    qc.proc.send_signal(signal.SIGKILL)  # by PID: no goodbye, no summary
    qc.proc.wait(timeout=10)
    last_frames = frames_before  # frames received after the last /api/state are not counted
    rec = read(one_file(tmp_path / "rec"))
    assert not rec.complete
    assert any("streaming order" in e for e in rec.errors), rec.errors
    frames = rec.topic("/stream/frame")
    first_seq = frames[0].data["sequence"] if frames else 0
    recovered = len(frames)
    expected = last_frames - first_seq
    span = rec.span_s()
    fraction = recovered / max(1, expected)
    print(
        f"SIGKILL after {FLIGHT_S:.0f} s: {recovered} of {expected} frames recovered "
        f"({100 * fraction:.1f} %), span {span:.2f} s, load {os.getloadavg()[0]:.1f}"
    )
    # The writer closes a chunk every second: at most ~1 s (plus the queue) is lost, besides what a
    # starved writer dropped (counted; every dropped event at most one frame).
    fps = state["stream"]["fps"] or 30.0
    dropped = state["recording"]["dropped_queue_full"]
    assert recovered >= expected - 2.5 * fps - dropped, (recovered, expected, fps, dropped)
    assert counts_ok(rec)


def counts_ok(rec) -> bool:
    c = rec.counts()
    return c.get("/control/command", 0) > 0 and c.get("/camera/rgb/compressed", 0) > 0


def test_full_disk_stops_recording_with_the_cause_and_the_flight_goes_on(
    binary, firmware, tmp_path
):
    double, b = firmware
    limit = 3 * 1024 * 1024  # a few seconds of recording

    def small_disk():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    qc = start(binary, tmp_path, b.port, tmp_path / "rec", preexec_fn=small_disk)
    try:
        api_post(qc.url, "api/command", {"command": "arm"})
        st = wait_for(
            lambda: (s := api_state(qc.url))["recording"]["failed"] and s, "the recording to fail"
        )
        assert "File too large" in st["recording"]["error"]
        frames, sent = st["stream"]["frames"], st["firmware"]["sent"]
        time.sleep(3.0)
        after = api_state(qc.url)
        assert (
            after["stream"]["frames"] > frames and after["firmware"]["sent"] > sent
        )  # the flight goes on
        assert after["recording"]["dropped_after_failure"] > 0
        assert double.last_command() is not None
    finally:
        qc.stop()
    log = "".join(qc.log)
    assert log.count("recording stopped") == 1, log
    rec = read(one_file(tmp_path / "rec"))
    assert rec.messages and os.path.getsize(one_file(tmp_path / "rec")) <= limit


def test_a_short_recording_replays_through_slam_within_tolerance(binary, firmware, tmp_path):
    _double, b = firmware
    qc = start(
        binary,
        tmp_path,
        b.port,
        tmp_path / "rec",
        stream={"loop": "once", "speed": SLOW_REPLAY_SPEED},
    )
    try:
        wait_for(
            lambda: "replay finished" in json.dumps(api_state(qc.url)), "the excerpt to play once"
        )
        time.sleep(1.0)  # the last poses reach the recorder
    finally:
        qc.stop()
    result = replay(
        one_file(tmp_path / "rec"),
        tmp_path / "replay",
        REPO / "build/bin/slam-eval",
        REPO / "build/bin/tum-score",
    )
    print(
        "replay of a short recording:",
        json.dumps(
            {
                k: result[k]
                for k in (
                    "frames",
                    "flight_poses",
                    "replay_poses",
                    "pairs",
                    "ate_replay_vs_flight_rmse_m",
                    "ate_replay_vs_flight_max_m",
                )
            }
        ),
    )
    assert result["frames"] >= 25, result  # every frame of the excerpt recorded (a few may drop)
    assert result["pairs"] >= 5, result
    assert result["ate_replay_vs_flight_rmse_m"] <= REPLAY_TOLERANCE_M, result
