"""LiveKinect unit tests: the FIFO index protocol fakenect relies on, newest-request-wins, records,
capture-stamp matching and per-frame reproducibility. A Python reader stands in for fakenect (one
line at a time, the named files opened after their line). Only the renderer child is started; the
frames are 160x120 so the whole file runs in a few seconds. Deterministic: seeded; no timing
assertions.
"""

from __future__ import annotations

import dataclasses
import json
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from kinect_emulator import Box, Intrinsics, KinectEmulator, KinectOptions, Room, pose_matrix
from kinect_emulator.live import (
    INDEX_NAME,
    READER_STALLED_S,
    RECORDS_NAME,
    SYNC_CONTENT,
    SYNC_NAME,
    SYNC_POLL_S,
    TILT_STATE,
    FakenectFifoIndex,
    LiveFrameRecord,
    LiveKinect,
    accel_counts,
    acceleration_from_poses,
    match_capture_stamps,
)
from kinect_emulator.writers import depth_mm_to_freenect_raw

SMALL = Intrinsics(width=160, height=120, fx=129.0, fy=129.0, cx=79.5, cy=59.5)
WAIT_S = 30.0  # generous: the machine is shared; only a hang would reach it


@pytest.fixture(scope="module")
def room():
    tex = np.random.default_rng(0).integers(0, 256, (3, 48, 64, 3), dtype=np.uint8)
    return Room(bounds=Box((-4.0, -3.0, 0.0), (4.0, 3.0, 3.0)), textures=tex)


def opts(seed: int = 5) -> KinectOptions:
    return KinectOptions(intrinsics=SMALL, seed=seed)


def level_pose(x: float) -> np.ndarray:
    # Camera looking along room +x (camera z), image x to room -y, image y down (room -z).
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return pose_matrix(R, [x, 0.0, 1.5])


def wait_for(pred, timeout_s: float = WAIT_S) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return pred()


class FakeFakenect:
    """Reads INDEX lines one at a time like fakenect's fgetc loop and opens each named file right
    after its line; records (line, file bytes) until EOF."""

    def __init__(self, dump: Path) -> None:
        self.dump = dump
        self.items: list[tuple[str, bytes]] = []
        self.missing: list[str] = []
        self.eof = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        with open(self.dump / INDEX_NAME, "rb") as f:  # blocks until the child opened the FIFO
            for line in f:
                name = line.decode().strip()
                try:
                    self.items.append((name, (self.dump / name).read_bytes()))
                except FileNotFoundError:
                    self.missing.append(name)
        self.eof.set()


def rec(i: int, written_s: float, delivered: bool = True) -> LiveFrameRecord:
    return LiveFrameRecord(i, i, written_s - 0.03, np.eye(4), 0.0, 0.0, written_s, delivered, 0,
                           f"d{i}", f"r{i}")  # fmt: skip


# ---- capture-stamp matching -------------------------------------------------------------------
@pytest.mark.parametrize(
    "stamp_us, want",
    [
        (999_000, None),  # before any line was written
        (1_000_000, 0),  # at the write instant
        (1_000_400, 0),
        (1_033_310, 1),
        (1_066_000, 1),  # frame 2 was not delivered: its stamp can only be frame 1's
        (1_100_000, 3),
        (1_250_001, None),  # more than max_delay after the last write
    ],
)
def test_match_capture_stamps(stamp_us, want):
    records = [rec(0, 1.0), rec(1, 1.0333), rec(2, 1.0666, delivered=False), rec(3, 1.1)]
    got = match_capture_stamps(records, [stamp_us], max_delay_us=150_000)[0]
    assert (got.index if got is not None else None) == want


# ---- the FIFO index (what fakenect reads) ------------------------------------------------------
def test_fifo_index_sync_protocol_files_complete_and_collected(tmp_path):
    """GIVEN a fakenect-like reader WHEN frames are written after wait_reader_done THEN the reader
    sees sync, d, r, sync, d, r, ... with every file complete when its line is read, the %c-%lf-%u
    name fields fakenect parses, and the files of every frame followed by a read sync deleted."""
    os.mkfifo(tmp_path / INDEX_NAME)
    idx = FakenectFifoIndex(tmp_path)
    idx.open()
    reader = FakeFakenect(tmp_path)
    rng = np.random.default_rng(1)
    frames = []
    try:
        for k in range(5):
            raw = rng.integers(0, 2048, (4, 5), dtype=np.uint16)
            rgb = rng.integers(0, 256, (4, 5, 3), dtype=np.uint8)
            assert idx.wait_reader_done(time.monotonic, time.sleep, WAIT_S)
            written, dname, rname = idx.write_frame(k, 12.5 + k, rgb, raw, lambda k=k: 100.0 + k)
            assert written == 100.0 + k == idx.last_written_s
            frames.append((dname, rname, raw, rgb))
        assert idx.wait_reader_done(time.monotonic, time.sleep, WAIT_S)  # the reader is done
        assert not idx.reader_is_behind()
        assert not [p for p in tmp_path.iterdir() if p.suffix in (".pgm", ".ppm", ".tmp")]
    finally:
        idx.close()
    assert reader.eof.wait(WAIT_S) and not reader.missing
    want = []
    for dname, rname, raw, rgb in frames:
        want += [
            (SYNC_NAME, SYNC_CONTENT),
            (dname, b"P5 5 4 65535\n" + raw.astype("=u2").tobytes()),
            (rname, b"P6 5 4 255\n" + rgb.tobytes()),
        ]
    assert reader.items == want + [(SYNC_NAME, SYNC_CONTENT)]
    for k, (dname, rname, _, _) in enumerate(frames):
        # fakenect's sscanf("%c-%lf-%u-%*s"): no pacing time, 60 MHz exposure ticks.
        for name, typ, ext in ((dname, "d", "pgm"), (rname, "r", "ppm")):
            c, t, ticks, rest = name.split("-", 3)
            want = (typ, 0.0, int((12.5 + k) * 60e6), f"{k}.{ext}")
            assert (c, float(t), int(ticks), rest) == want
    assert SYNC_CONTENT  # fakenect ends the dump on a 0-byte file


def test_accelerometer_counts_from_truth_attitude_and_acceleration():
    """GIVEN the camera's truth pose and acceleration THEN the counts are the specific force a - g
    in the accelerometer's axes at 819 counts/g, clipped at +-2 g."""
    T = level_pose(0.0)
    assert accel_counts(T, np.zeros(3)) == (0, 819, 0)  # at rest: 1 g up = sensor +y
    # Accelerating forward (room +x = camera z = sensor z) at 1 g: +819 on z as well.
    assert accel_counts(T, np.array([9.80665, 0.0, 0.0])) == (0, 819, 819)
    # Free fall reads nothing; 3 g up is clipped at the sensor's +2 g.
    assert accel_counts(T, np.array([0.0, 0.0, -9.80665])) == (0, 0, 0)
    assert accel_counts(T, np.array([0.0, 0.0, 2 * 9.80665])) == (0, 1638, 0)
    # A camera pitched 90 deg down (optical axis = room -z): gravity's reaction is along -z_cam.
    down = pose_matrix(np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]), [0, 0, 1])
    assert accel_counts(down, np.zeros(3)) == (0, 0, -819)


def test_acceleration_from_poses_fits_the_curvature_and_averages_time_jitter():
    h = [(0.0, np.zeros(3)), (0.1, np.array([0.01, 0.0, 0.0])), (0.2, np.array([0.04, 0.0, 0.0]))]
    np.testing.assert_allclose(acceleration_from_poses(h), [2.0, 0.0, 0.0], atol=1e-9)  # x = t^2
    assert not acceleration_from_poses(h[:2]).any()
    assert not acceleration_from_poses([h[0], h[0], h[1]]).any()  # no time between two samples
    # GIVEN a camera accelerating at 0.5 m/s^2 along y, sampled at 30 fps with request times off
    # by up to 1 ms from the poses' THEN the fit is within 0.5 m/s^2 (a second difference is not)
    rng = np.random.default_rng(4)
    t = np.arange(20) / 30.0
    hist = [(tk + rng.uniform(-1e-3, 1e-3), np.array([0.0, 0.25 * tk**2, 1.5])) for tk in t]
    np.testing.assert_allclose(acceleration_from_poses(hist), [0.0, 0.5, 0.0], atol=0.5)


def test_fifo_index_without_reader_times_out_and_keeps_files(tmp_path):
    """GIVEN nobody reads the FIFO WHEN waiting for the reader THEN it gives up at the deadline
    (clock passed in) with only the sync line queued, and no frame file is ever deleted."""
    os.mkfifo(tmp_path / INDEX_NAME)
    idx = FakenectFifoIndex(tmp_path)
    idx.open()
    now = [0.0]
    sleeps = []

    def sleep(s):
        sleeps.append(s)
        now[0] += s

    try:
        assert not idx.wait_reader_done(lambda: now[0], sleep, 0.01)
        assert now[0] >= 0.01 and len(sleeps) == pytest.approx(0.01 / SYNC_POLL_S, abs=2)
        assert idx.unread_bytes() == len(SYNC_NAME) + 1
        assert not idx.wait_reader_done(lambda: now[0], sleep, 0.01)
        assert idx.unread_bytes() == len(SYNC_NAME) + 1  # no second sync while one is unread
        for k in range(3):
            idx.write_frame(k, 1.0, np.zeros((2, 2, 3), np.uint8), np.zeros((2, 2), np.uint16),
                            lambda: 0.0)  # fmt: skip
        idx.collect()
        assert len([p for p in tmp_path.iterdir() if p.suffix in (".pgm", ".ppm")]) == 6
    finally:
        idx.close()


# ---- per-frame reproducibility -----------------------------------------------------------------
def test_render_indexed_is_a_function_of_pose_and_index(room):
    T = level_pose(-1.0)
    a = KinectEmulator(room, opts()).render_indexed(T, 0, 7)
    emu = KinectEmulator(room, opts())
    seq_before = KinectEmulator(room, opts()).render(T, 0)
    emu.render_indexed(level_pose(0.5), 0, 3)
    b = emu.render_indexed(T, 0, 7)
    c = emu.render_indexed(T, 0, 8)
    seq_after = emu.render(T, 0)  # the sequential stream is untouched by render_indexed
    assert np.array_equal(a.depth_mm, b.depth_mm) and np.array_equal(a.rgb, b.rgb)
    assert not np.array_equal(a.depth_mm, c.depth_mm)  # different noise draw
    assert np.array_equal(seq_before.depth_mm, seq_after.depth_mm)
    assert np.array_equal(seq_before.rgb, seq_after.rgb)


# ---- the live camera (renderer child) ----------------------------------------------------------
def test_submit_validation_and_not_started(tmp_path, room):
    cam = LiveKinect(tmp_path / "d", opts(), room)
    with pytest.raises(ValueError):
        cam.submit(0.0, np.eye(3))
    with pytest.raises(ValueError):
        cam.submit(float("nan"), np.eye(4))
    bad = np.eye(4)
    bad[0, 3] = np.inf
    with pytest.raises(ValueError):
        cam.submit(0.0, bad)
    assert cam.submit(0.0, level_pose(0.0)) is False  # not started
    assert cam.stats()["send_failed"] == 1


def test_start_refuses_an_offline_dump(tmp_path, room):
    (tmp_path / INDEX_NAME).write_text("d-1.0-1-0.pgm\n")
    with pytest.raises(FileExistsError):
        LiveKinect(tmp_path, opts(), room).start()
    assert (tmp_path / INDEX_NAME).read_text() == "d-1.0-1-0.pgm\n"


def test_live_frames_reach_a_reader_in_order_and_reproducibly(tmp_path, room):
    dump = tmp_path / "live"
    cam = LiveKinect(dump, opts(seed=9), room)  # frame files deleted once read: none may be missing
    cam.start()
    try:
        reader = FakeFakenect(dump)

        def frames_read():  # images only (not the sync lines, not the accelerometer records)
            return [item for item in reader.items if item[0] != SYNC_NAME and item[0][0] != "a"]

        poses = [level_pose(-2.0 + 0.1 * k) for k in range(8)]
        for k, T in enumerate(poses):
            assert cam.submit(10.0 + k / 30, T)
            # One at a time (wait for the record): nothing is superseded, nothing is behind.
            assert wait_for(
                lambda k=k: len(cam.records()) == k + 1 and len(frames_read()) == 2 * k + 2
            )
        # An out-of-room pose: an error record, no frame, the camera goes on.
        assert cam.submit(20.0, level_pose(50.0))
        assert wait_for(lambda: cam.error_messages())
        assert cam.alive()
    finally:
        cam.close()
    assert not cam.alive()
    assert reader.eof.wait(WAIT_S), "the reader never saw EOF after close()"
    assert not reader.missing
    # A sync line before every frame: the reader finished the previous frame before the next. Each
    # frame's accelerometer record comes before its images (the streamer reads it after the image).
    all_names = [item[0] for item in reader.items]
    assert all_names[1].startswith("a-") and all_names[2].startswith("d-")
    names = [n for n in all_names if not n.startswith("a-")]
    assert names[:4] == [SYNC_NAME, recs_first_d := names[1], names[2], SYNC_NAME]
    assert recs_first_d.startswith("d-") and names[2].startswith("r-")
    # The camera moves at constant velocity along x, level: the accelerometer reads 1 g up, which
    # is the sensor's +y (x left, y up, z forward), within 6 sigma of the noise (0.05 m/s^2 = 4.2
    # counts).
    for name, data in reader.items:
        if name.startswith("a-"):
            x, y, z, _, _ = TILT_STATE.unpack(data)
            assert abs(x) <= 25 and abs(y - 819) <= 25 and abs(z) <= 25, (name, x, y, z)
    assert not (dump / INDEX_NAME).exists()  # the FIFO is removed; the records stay
    assert (dump / RECORDS_NAME).exists()
    recs = cam.records()
    assert [r.index for r in recs] == list(range(8))
    assert [r.request_seq for r in recs] == list(range(8))
    assert "outside the room" in cam.error_messages()[0]
    st = cam.stats()
    assert (st["submitted"], st["delivered"], st["errors"], st["dropped"]) == (9, 8, 1, 1)
    emu = KinectEmulator(room, opts(seed=9))
    for k, r in enumerate(recs):
        assert np.array_equal(r.T_room_cam, poses[k])
        assert r.t_mono_s == 10.0 + k / 30
        assert r.render_start_mono_s <= r.render_end_mono_s <= r.index_written_mono_s
        dname, dbytes = frames_read()[2 * k]
        rname, rbytes = frames_read()[2 * k + 1]
        assert (dname, rname) == (r.depth_file, r.rgb_file)
        f = emu.render_indexed(poses[k], round(r.t_mono_s * 1e6), r.index)
        h, w = f.depth_mm.shape
        assert (
            dbytes
            == f"P5 {w} {h} 65535\n".encode()
            + depth_mm_to_freenect_raw(f.depth_mm).astype("=u2").tobytes()
        )
        assert rbytes == f"P6 {w} {h} 255\n".encode() + f.rgb.tobytes()


def test_newest_request_wins_and_nothing_queues_without_a_reader(tmp_path, room):
    """GIVEN nobody reads the FIFO WHEN a burst of requests arrives THEN the first is rendered but
    dropped once its sync line goes unread for FAKENECT_WAIT_S, later ones are not even rendered,
    nothing is queued in the FIFO but that sync line, requests waiting while the child works are
    superseded, and the newest request is served."""
    dump = tmp_path / "live"
    cam = LiveKinect(dump, opts(), room)
    cam.start()
    try:
        n = 40
        for k in range(n):
            assert cam.submit(float(k), level_pose(-2.0 + 0.01 * k))
        assert wait_for(
            lambda: any(
                json.loads(line)["seq"] == n - 1
                for line in (dump / RECORDS_NAME).read_text().splitlines()
            )
        )
        st = cam.stats()
        time.sleep(READER_STALLED_S + 0.2)
        assert cam.submit(float(n), level_pose(-1.0))
        assert wait_for(lambda: cam.stats()["reader_behind"] == st["reader_behind"] + 1)
        st_late = cam.stats()
    finally:
        cam.close()
    assert cam.records() == []
    assert (st["delivered"], st["rendered"], st["pending"]) == (0, 1, 0)
    assert st["reader_behind"] + st["superseded"] == n == st["dropped"]
    assert st_late["rendered"] == 1
    assert not list(dump.glob("d-*.pgm"))


def test_streamer_command_and_env(tmp_path, room, monkeypatch):
    import kinect_emulator.live as live

    cam = LiveKinect(tmp_path / "d", opts(), room)
    assert cam.streamer_command("/b/rgbd-streamer", "--host", "127.0.0.1", "--rgb-port", 5) == [
        "fakenect", str(tmp_path / "d"), "/b/rgbd-streamer", "--source", "freenect",
        "--freenect-disparity-depth", "--host", "127.0.0.1", "--rgb-port", "5",
    ]  # fmt: skip
    assert cam.direct_streamer_command("/b/s") == [
        "/b/s", "--source", "freenect", "--freenect-disparity-depth"
    ]  # fmt: skip
    monkeypatch.setattr(live, "fakenect_lib_dir", lambda: "/lib/fk")
    env = cam.streamer_env({"LD_LIBRARY_PATH": "/x", "HOME": "/h"})
    assert env == {
        "LD_LIBRARY_PATH": "/lib/fk:/x",
        "HOME": "/h",
        "FAKENECT_PATH": str(tmp_path / "d"),
    }
    assert cam.streamer_env({})["LD_LIBRARY_PATH"] == "/lib/fk"
    monkeypatch.setattr(live, "fakenect_lib_dir", lambda: None)
    with pytest.raises(FileNotFoundError):
        cam.streamer_env({})


def test_given_a_sensor_latency_then_each_frame_is_held_until_exposure_plus_latency(tmp_path, room):
    """KinectOptions.latency_ms (the Kinect's exposure -> USB delay) delays the INDEX line."""
    dump = tmp_path / "live"
    latency_ms = 150.0  # well above a render of this small image, so the hold is what is measured
    cam = LiveKinect(dump, dataclasses.replace(opts(), latency_ms=latency_ms), room)
    cam.start()
    try:
        FakeFakenect(dump)
        t_exposure = time.monotonic()
        assert cam.submit(t_exposure, level_pose(0.0))
        assert wait_for(lambda: len(cam.records()) == 1)
    finally:
        cam.close()
    r = cam.records()[0]
    assert r.index_written_mono_s - r.t_mono_s >= latency_ms / 1e3
    assert cam.stats()["renderer"] in ("cpp", "numpy")
