"""HIL: LIVE emulated Kinect -> real libfreenect API (Debian's fakenect, INDEX.txt a FIFO) -> real
rgbd-streamer -> loopback receiver, rendering from poses submitted at the frame rate.

GIVEN a LiveKinect and rgbd-streamer (freenect source, 11-bit disparity mode) started on its dump,
WHEN poses along a short path are submitted at 15 and then 30 fps for a few seconds (paced to the
wall clock like the closed-loop rig), THEN depth and RGB frames arrive in INDEX order, every one
matches a record by its capture stamp (match_capture_stamps), its depth equals the renderer's output
for that record's pose after the 11-bit disparity round trip (re-rendered here) and its RGB equals
the render bit for bit; frame files are deleted as fakenect finishes with them.
Reported (printed and test-artifacts/hil/live_kinect.json): delivered fps, dropped frames, render
ms, latency exposure -> INDEX written -> streamer capture stamp -> received (median/p95).
"""

from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest
from hilrig.paths import artifacts_dir, find_binary
from hilrig.procs import ManagedProcess
from hilrig.stream_rx import StreamReceiver
from kinect_emulator import KinectEmulator, KinectOptions, camera_pose_from_ned, default_room
from kinect_emulator.live import LiveKinect, fakenect_lib_dir, match_capture_stamps
from kinect_emulator.writers import depth_mm_to_freenect_raw, freenect_raw_to_depth_mm
from rgbd_protocol.stream_auth import write_key_file

pytestmark = pytest.mark.hil

DURATION_S = 3.0  # per rate: ~45 / ~90 frames, enough for median/p95 on a shared machine
SEED = 7
CONNECT_TIMEOUT_S = 20.0


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    streamer = find_binary("rgbd-streamer")
    if streamer is None:
        pytest.skip("rgbd-streamer is not built (RGBD_BUILD_DIR/bin)")
    if fakenect_lib_dir() is None:
        pytest.skip("fakenect library not installed (libfreenect-bin)")
    room = default_room()
    return dict(streamer=streamer, room=room, work=tmp_path_factory.mktemp("live_kinect"))


def _pose(s: float) -> np.ndarray:
    """A slow forward drift with a yaw turn (s in seconds of flight)."""
    return camera_pose_from_ned(
        [0.15 * s, 0.05 * s, -1.5], 0.01, -0.02, 0.1 * s, 30.0, origin_room_m=(-1.5, 0.5, 0.2)
    )


def _wait(pred, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return pred()


def _stats(values_ms) -> dict:
    a = np.asarray(values_ms, dtype=float)
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95))}


def _fly(setup, fps: float) -> dict:
    work = setup["work"] / f"fps{int(fps)}"
    work.mkdir()
    opts = KinectOptions(fps=fps, seed=SEED)
    # Frame files are deleted as fakenect finishes with them: a premature deletion would stop the
    # streamer ("Cannot open file") and fail the frame counts below.
    cam = LiveKinect(work / "dump", opts, room=setup["room"])
    cfg = work / "streamer.yaml"
    key = work / "stream.key"  # the craft's stream key, shared with the receiver (mode 0600)
    write_key_file(key)
    cfg.write_text(
        cam.streamer_config_yaml(
            f"stats_period_s: 0\nlog_level: warn\nexit_linger_ms: 1000\nstream_key_file: {key}\n"
        )
    )
    with StreamReceiver(key) as rx:
        cam.start()
        try:
            argv = cam.direct_streamer_command(
                setup["streamer"], "-c", cfg, "--host", "127.0.0.1",
                "--rgb-port", rx.rgb_port, "--depth-port", rx.depth_port,
                "--depth-encoding", "raw", "--rgb-encoding", "raw",
            )  # fmt: skip
            with ManagedProcess(argv, work / "streamer.log", env=cam.streamer_env()) as proc:
                connected = _wait(lambda: len(rx.handshakes) == 2, CONNECT_TIMEOUT_S)
                assert connected, proc.log_text()[-2000:]
                n = int(DURATION_S * fps)
                t_start = time.monotonic()
                for k in range(n):
                    due = t_start + k / fps
                    time.sleep(max(0.0, due - time.monotonic()))
                    assert cam.submit(time.monotonic(), _pose(k / fps))
                time.sleep(max(0.0, t_start + n / fps - time.monotonic()))
                flown_s = time.monotonic() - t_start
                _wait(lambda: len(rx.frames("depth")) >= len(cam.records()), 2.0)
                cam.close()  # EOF on the FIFO: the streamer's freenect source ends
                _wait(lambda: not proc.alive(), 10.0)
                log = proc.log_text()
        finally:
            cam.close()
        depth, rgb = rx.frames("depth"), rx.frames("rgb")
        scale = rx.handshakes["depth"]["depth_scale_units_per_m"]
    return dict(
        cam=cam,
        opts=opts,
        depth=depth,
        rgb=rgb,
        scale=scale,
        log=log,
        flown_s=flown_s,
        n=n,
        dump=work / "dump",
    )


@pytest.mark.parametrize("fps", [15.0, 30.0])
def test_live_kinect_through_fakenect_and_rgbd_streamer(setup, fps):
    run = _fly(setup, fps)
    cam, depth, rgb = run["cam"], run["depth"], run["rgb"]
    recs = cam.records()
    st = cam.stats()
    assert depth and rgb, run["log"][-2000:]
    assert run["scale"] == 1000.0

    # Order: the streamer's frames come in INDEX order.
    d_match = match_capture_stamps(recs, [f.capture_timestamp_us for f in depth])
    r_match = match_capture_stamps(recs, [f.capture_timestamp_us for f in rgb])
    assert all(m is not None for m in d_match + r_match), "a streamer frame matches no record"
    assert [f.sequence for f in depth] == sorted(f.sequence for f in depth)
    d_idx = [m.index for m in d_match]
    assert d_idx == sorted(set(d_idx)), "depth frames out of order or duplicated"

    # Content: the renderer's output for the record's pose (re-rendered here: a frame is a pure
    # function of pose and index), depth after the 11-bit disparity round trip, RGB bit for bit.
    emu = KinectEmulator(setup["room"], run["opts"])
    refs = {}

    def ref(m):
        if m.index not in refs:
            refs[m.index] = emu.render_indexed(m.T_room_cam, int(round(m.t_mono_s * 1e6)), m.index)
        return refs[m.index]

    for f, m in zip(depth, d_match, strict=False):
        got = np.frombuffer(f.payload, dtype="<u2").reshape(f.height, f.width)
        want = freenect_raw_to_depth_mm(depth_mm_to_freenect_raw(ref(m).depth_mm))
        assert np.array_equal(got, want), f"depth of frame {m.index} is not the render of its pose"
    for f, m in zip(rgb, r_match, strict=False):
        got = np.frombuffer(f.payload, np.uint8).reshape(f.height, f.width, 3)
        assert np.array_equal(got, ref(m).rgb), f"RGB of frame {m.index} is not the render"
    # Files fakenect finished with were deleted during the flight (the last frame's may remain).
    assert len(list(run["dump"].glob("d-*.pgm"))) <= 1

    # Latency chain (ms), over the depth frames received.
    exp_to_written = [(m.index_written_mono_s - m.t_mono_s) * 1e3 for m in d_match]
    written_to_capture = [
        f.capture_timestamp_us / 1e3 - m.index_written_mono_s * 1e3
        for f, m in zip(depth, d_match, strict=False)
    ]
    capture_to_rx = [(f.receive_monotonic_us - f.capture_timestamp_us) / 1e3 for f in depth]
    exp_to_rx = [
        f.receive_monotonic_us / 1e3 - m.t_mono_s * 1e3
        for f, m in zip(depth, d_match, strict=False)
    ]
    assert min(written_to_capture) >= 0 and min(capture_to_rx) >= 0
    report = {
        "load_average_1_5_15min": list(os.getloadavg()),  # 2 shared cores: read figures with it
        "fps_submitted": fps,
        "flown_s": run["flown_s"],
        "submitted": st["submitted"],
        "pending_at_close": st["pending"],
        "rendered": st["rendered"],
        "delivered_to_fakenect": st["delivered"],
        "dropped": st["dropped"],
        "superseded": st["superseded"],
        "reader_behind": st["reader_behind"],
        "depth_received": len(depth),
        "rgb_received": len(rgb),
        "delivered_fps": st["delivered"] / run["flown_s"],
        "depth_received_fps": len(depth) / run["flown_s"],
        "render_ms": {"median": st["render_ms_median"], "p95": st["render_ms_p95"]},
        "exposure_to_index_written_ms": _stats(exp_to_written),
        "index_written_to_capture_stamp_ms": _stats(written_to_capture),
        "capture_stamp_to_received_ms": _stats(capture_to_rx),
        "exposure_to_received_ms": _stats(exp_to_rx),
    }
    path = artifacts_dir() / "live_kinect.json"
    old = json.loads(path.read_text()) if path.exists() else {}
    path.write_text(json.dumps({**old, f"fps{int(fps)}": report}, indent=2))
    print(f"\nlive kinect @ {fps:g} fps:", json.dumps(report))
    # Every frame the child wrote reached the streamer's freenect callbacks in order; the streamer
    # forwards the newest frames (it may supersede some on its own).
    assert st["delivered"] >= 0.5 * run["n"]
    assert len(depth) >= 0.5 * st["delivered"]
