"""Live Kinect: renders frames from the craft's CURRENT pose and feeds them to the real
rgbd-streamer through the real libfreenect API (Debian's fakenect replay library), for closed-loop
HIL flights.

How it works
  * `dump_dir/INDEX.txt` is a FIFO (os.mkfifo). fakenect 0.5.3 reads INDEX.txt one line per
    `freenect_process_events` call with fgetc, so the streamer's libfreenect event thread blocks in
    read() until the next line arrives, then opens the named PGM/PPM, copies it into the depth/video
    buffer and calls the callback (where rgbd-streamer stamps `capture_timestamp_us` on
    CLOCK_MONOTONIC). Measured here: the callback runs < 1 ms after the line is written.
  * A renderer child process (`python -m kinect_emulator.live_child`: its own GIL; a subprocess
    rather than multiprocessing, so the caller's __main__ is never re-imported) takes the newest
    pose request, renders RGB + depth (KinectEmulator.render_indexed, Kinect noise model of
    docs/hil.md), writes `d-*.pgm` (11-bit disparity, host byte order, as FakenectDumpWriter)
    and `r-*.ppm` under temporary names, renames them, and only then writes their two INDEX lines
    (one write() below PIPE_BUF, so atomic).
  * A camera never queues: requests arriving while the child renders replace each other (the newest
    wins, the others are counted as `superseded`). Before writing a frame's lines the child writes
    a sync line (`s-...-sync`, a 5-byte file fakenect opens and ignores) and waits until fakenect
    has read it, which it does only after the previous frame's callbacks returned (stdio reads the
    FIFO again only when it has used up what it read). So the FIFO never holds more than one frame,
    and every capture stamp of frame k lies between frame k's and frame k+1's write times
    (`match_capture_stamps` is exact). A frame whose sync is not read within FAKENECT_WAIT_S is
    dropped (`reader_behind`: the streamer is slow, stalled or not started); once lines have stayed
    unread for READER_STALLED_S, requests are not even rendered.
  * fakenect sleeps by the difference of the time field of consecutive lines (only if positive;
    never when the previous value is 0). Live lines carry 0.000000 there: the writer paces, fakenect
    adds no delay. The %u field carries the exposure time in 60 MHz ticks, like real dumps.
  * Before the first line the streamer simply waits (fopen of the FIFO returns once the child has
    it open; fgetc blocks). When the child closes the FIFO (close(), or the child dies), fakenect
    prints "No more lines", freenect_process_events returns -1 and rgbd-streamer ends its freenect
    source (exit code 3 after --exit-linger-ms). Close the LiveKinect BEFORE stopping the streamer:
    a streamer stopped by SIGTERM joins its event thread, which only returns at the next line / EOF.
  * A frame's files are deleted once the sync line after it has been read (fakenect is done with
    them), so a long flight keeps one or two frames (~1.5 MB each) on disk; `keep_files=True` keeps
    all.

Records: one JSON line per rendered frame in `dump_dir/live_frames.jsonl` (written by the child,
flushed per frame; the parent reads it in `records()`). Time is time.monotonic() (CLOCK_MONOTONIC),
the clock rgbd-streamer stamps frames with on the same host; `match_capture_stamps` maps streamer
capture stamps to records.

Usage (the rig thread calls submit() at the frame rate; it never waits for the renderer):
    cam = LiveKinect(tmp / "live", KinectOptions(seed=3))
    cam.start()
    streamer = ManagedProcess(cam.direct_streamer_command(bin, "--host", "127.0.0.1", ...),
                              log, env=cam.streamer_env())    # the streamer's own PID
    ... cam.submit(time.monotonic(), T_room_cam) every 1/fps s ...
    cam.close(); streamer.wait(...) / streamer.stop()
`streamer_command()` gives the `fakenect <dump> <streamer> ...` wrapper form instead (its PID is a
bash that does not exec: stopping it leaves the streamer running until close()). Frames submitted
before the streamer opens the FIFO are dropped (`reader_behind`); none is queued for it.
Measured (hil/scenarios/test_live_kinect.py, 2 shared cores): render ~15 ms per 640x480 frame in
the child, 30 fps sustained, INDEX written -> streamer capture stamp ~0.35 ms.
Thread safety: submit() may be called from one thread while another calls records()/stats();
start() and close() from the owning thread.
"""

from __future__ import annotations

import fcntl
import json
import logging
import math
import os
import re
import shutil
import stat
import struct
import subprocess
import termios
import threading
import time
from bisect import bisect_right
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rgbd_protocol.tum_cameras import KINECT_V1_ACCELEROMETER

from kinect_emulator.renderer import KinectEmulator, KinectOptions
from kinect_emulator.room import Room, default_room
from kinect_emulator.writers import depth_mm_to_freenect_raw

_log = logging.getLogger(__name__)

INDEX_NAME = "INDEX.txt"
RECORDS_NAME = "live_frames.jsonl"
# Default location of Debian's fakenect library (libfreenect-bin's wrapper sets the same).
DEFAULT_FAKENECT_LIB_DIR = "/usr/lib/x86_64-linux-gnu/fakenect"
# fakenect's pacing field: with 0 the "previous time != 0" guard skips its sleep entirely.
FAKENECT_NO_PACING_TIME = "0.000000"
FAKENECT_TICKS_PER_S = 60_000_000  # real dumps carry the Kinect's 60 MHz device clock
# Request message: sequence (int64, -1 = stop), exposure time (s, float64), T_room_cam row-major.
_REQUEST = struct.Struct("<qd16d")
_STOP_SEQ = -1
# The child starts in ~1 s (numpy import, texture loading); allow for a loaded 2-core machine.
START_TIMEOUT_S = 60.0
CLOSE_TIMEOUT_S = 10.0
# fakenect reads a line < 1 ms after it is written (p95 < 5 ms on the loaded 2-core machine); lines
# unread this long after the last frame was written mean the streamer is not reading (not started,
# stopped, stalled): new requests are then not even rendered. Several frame periods, so mere jitter
# never skips a render.
READER_STALLED_S = 0.1
# match_capture_stamps: a callback this long after its line means the stamp is not this camera's
# (measured: < 1 ms median, < 5 ms p95 on the loaded machine; 1 s leaves room for any stall).
MATCH_MAX_DELAY_US = 1_000_000
# Sync line: type 's' is neither depth, video nor accelerometer, so fakenect reads the file and
# calls nothing. The file must not be empty: fakenect takes a failed 0-byte fread as the end.
SYNC_NAME = "s-0.000000-0-sync"
SYNC_LINE = (SYNC_NAME + "\n").encode()
SYNC_CONTENT = b"sync\n"
# How long the child waits for fakenect to finish the previous frame before it drops a rendered one
# (fakenect reads the sync line < 1 ms after it is written when idle; the streamer's depth callback,
# 11-bit -> mm for 307 200 pixels, takes a few ms): 1.5 frame periods at 30 fps.
FAKENECT_WAIT_S = 0.05
SYNC_POLL_S = 0.0002  # 0.2 ms: well below the wait, a few hundred polls at most per frame
# The Kinect's accelerometer, written as fakenect accelerometer records ('a-*.dump': libfreenect's
# freenect_raw_tilt_state, int16 x y z counts, int8 tilt angle, int tilt status, native layout)
# before each frame's lines, so the streamer's freenect_update_tilt_state after the colour image
# reads it. Counts per g, g and the axes come from the one model (protocol/camera/tum_cameras.json).
ACCEL_MODEL = KINECT_V1_ACCELEROMETER
R_CAM_ACCEL = np.array(ACCEL_MODEL.R_cam_accel)
TILT_STATE = struct.Struct("@3hbi")  # freenect_raw_tilt_state on the streamer's host
# Truth samples the acceleration is fitted over: 7 requests = 0.23 s at 30 fps, long enough to
# average the request-time jitter, short next to a manoeuvre (the HIL scenarios' steps take ~1 s).
ACCEL_FIT_SAMPLES = 7
ACCEL_NOISE_STREAM = 0xACC  # (seed, this) seeds the accelerometer noise, apart from the images'
# Accelerometer noise, m/s^2 per axis (1 sigma): about 4 counts of 819/g, the spread of single
# samples of TUM's Kinect at rest (fr1 recordings: a few counts), before quantisation to counts.
ACCEL_NOISE_MPS2 = 0.05
# Gravity in the room frame (x north, y west, z up): the specific force at rest points up.
GRAVITY_ROOM_MPS2 = np.array([0.0, 0.0, -ACCEL_MODEL.standard_gravity_mps2])


def accel_counts(
    T_room_cam: np.ndarray, a_room_mps2: np.ndarray, noise_mps2: np.ndarray | None = None
) -> tuple[int, int, int]:
    """What the Kinect's accelerometer reads for a camera at T_room_cam accelerating at a_room
    (room frame): the specific force a - g rotated into the camera and then the accelerometer
    axes, plus noise, in counts (819/g), clipped at the sensor's range."""
    f_room = np.asarray(a_room_mps2, float) - GRAVITY_ROOM_MPS2
    f_cam = T_room_cam[:3, :3].T @ f_room
    f_accel = R_CAM_ACCEL.T @ f_cam
    if noise_mps2 is not None:
        f_accel = f_accel + noise_mps2
    per_count = ACCEL_MODEL.standard_gravity_mps2 / ACCEL_MODEL.counts_per_g
    limit = round(ACCEL_MODEL.range_g * ACCEL_MODEL.counts_per_g)
    counts = np.clip(np.rint(f_accel / per_count), -limit, limit).astype(int)
    return int(counts[0]), int(counts[1]), int(counts[2])


def acceleration_from_poses(history: list[tuple[float, np.ndarray]]) -> np.ndarray:
    """The camera's acceleration in the room frame from its recent (time, position) truth samples:
    the curvature of a least-squares parabola per axis over the last ACCEL_FIT_SAMPLES, so the
    sub-millisecond jitter between a request's time and its pose (amplified by 1/dt^2 in a plain
    second difference: 1 mm at 30 fps is 1.8 m/s^2) averages out; it lags by half the window.
    Zero until there are three samples spanning a positive time."""
    h = history[-ACCEL_FIT_SAMPLES:]
    if len(h) < 3:
        return np.zeros(3)
    t = np.array([x[0] for x in h], float)
    t = t - t[-1]
    if not np.ptp(t) > 0 or len(np.unique(t)) < 3:
        return np.zeros(3)
    p = np.array([x[1] for x in h], float)
    coeffs = np.polyfit(t, p, 2)  # rows: t^2, t, 1 coefficients, one column per axis
    return 2.0 * coeffs[0]


@dataclass(frozen=True)
class LiveFrameRecord:
    """One frame the child rendered. Times are time.monotonic() seconds (CLOCK_MONOTONIC)."""

    index: int  # render number: seeds the frame's noise (render_indexed); increases by 1 per render
    request_seq: int  # which submit() (0, 1, ...) it was rendered for
    t_mono_s: float  # exposure time given to submit()
    T_room_cam: np.ndarray  # 4x4 pose it was rendered at (maps camera points to room)
    render_start_mono_s: float  # the child took the request
    render_end_mono_s: float  # image computed (before the files were written)
    index_written_mono_s: float  # just before the INDEX lines were written; NaN if not delivered
    delivered: bool  # False: the streamer had not read the previous frame yet (never written)
    superseded: int  # requests dropped in favour of this one since the previous render
    depth_file: str
    rgb_file: str


def delivered_record(d: dict) -> LiveFrameRecord:
    """The record of a delivered frame from its line in the records file (RECORDS_NAME)."""
    return LiveFrameRecord(
        index=d["index"],
        request_seq=d["seq"],
        t_mono_s=d["t_mono_s"],
        T_room_cam=np.array(d["T_room_cam"]).reshape(4, 4),
        render_start_mono_s=d["render_start_mono_s"],
        render_end_mono_s=d["render_end_mono_s"],
        index_written_mono_s=d["index_written_mono_s"],
        delivered=True,
        superseded=d["superseded"],
        depth_file=d["depth_file"],
        rgb_file=d["rgb_file"],
    )


def match_capture_stamps(
    records: list[LiveFrameRecord], stamps_us, max_delay_us: int = MATCH_MAX_DELAY_US
) -> list[LiveFrameRecord | None]:
    """For each streamer capture stamp (us, CLOCK_MONOTONIC), the delivered record whose INDEX lines
    were written last before it, or None when there is none within max_delay_us. Exact for
    LiveKinect's records: frame k+1 is written only after fakenect finished frame k's callbacks (the
    sync line), so frame k's stamps lie in [written_k, written_k+1). max_delay_us only rejects
    stamps that cannot be this camera's (fakenect calls back within a few ms of the write)."""
    rs = sorted((r for r in records if r.delivered), key=lambda r: r.index_written_mono_s)
    written_us = [r.index_written_mono_s * 1e6 for r in rs]
    out: list[LiveFrameRecord | None] = []
    for s in stamps_us:
        k = bisect_right(written_us, float(s)) - 1
        out.append(rs[k] if k >= 0 and float(s) - written_us[k] <= max_delay_us else None)
    return out


def fakenect_lib_dir() -> str | None:
    """The directory the `fakenect` wrapper puts first on LD_LIBRARY_PATH, or None if not found."""
    wrapper = shutil.which("fakenect")
    if wrapper is not None:
        try:
            m = re.search(r'LD_LIBRARY_PATH="([^:"]+)', Path(wrapper).read_text(errors="replace"))
        except OSError:
            m = None
        if m and Path(m.group(1)).is_dir():
            return m.group(1)
    return DEFAULT_FAKENECT_LIB_DIR if Path(DEFAULT_FAKENECT_LIB_DIR).is_dir() else None


class FakenectFifoIndex:
    """Writes live frames into a fakenect dump whose INDEX.txt is a FIFO (used in the child).

    `open()` opens the FIFO read-write and non-blocking: it never waits for a reader, and the FIFO
    stays open (no EOF for the reader) until `close()`. Before a frame's lines, `wait_reader_done()`
    writes a sync line (a tiny file of a type fakenect reads and ignores) and waits until it leaves
    the FIFO: fakenect reads the FIFO only once it has processed every line it read before (the
    previous frame's callbacks have returned). So the streamer's capture stamps of frame k all lie
    between frame k's and frame k+1's write times, and frame k's files can then be deleted.
    Not thread-safe. Clock and sleep are passed in.
    """

    def __init__(self, dump_dir, keep_files: bool = False) -> None:
        self.dir = Path(dump_dir)
        self.keep_files = keep_files
        self._fd: int | None = None
        self.last_written_s = -math.inf  # clock time of the last frame's INDEX write
        self._bytes_written = 0
        self._on_disk: list[list] = []  # [files, offset after which fakenect is done with them]

    def open(self) -> None:
        sync = self.dir / SYNC_NAME
        tmp = self.dir / f".{SYNC_NAME}.tmp"
        tmp.write_bytes(SYNC_CONTENT)
        os.replace(tmp, sync)
        self._fd = os.open(self.dir / INDEX_NAME, os.O_RDWR | os.O_NONBLOCK)

    def unread_bytes(self) -> int:
        buf = fcntl.ioctl(self._fd, termios.FIONREAD, b"\0\0\0\0")
        return struct.unpack("i", buf)[0]

    def reader_is_behind(self) -> bool:
        """True while lines are unread in the FIFO."""
        return self.unread_bytes() > 0

    def _write(self, data: bytes) -> None:
        n = os.write(self._fd, data)  # < PIPE_BUF: whole and atomic
        if n != len(data):
            raise OSError(f"short write to the fakenect INDEX FIFO ({n} of {len(data)} bytes)")
        self._bytes_written += n

    def wait_reader_done(self, clock, sleep, timeout_s: float) -> bool:
        """True once the reader has processed every line written so far (see the class); False
        if that has not happened within timeout_s (the streamer is not reading, or is slow)."""
        deadline = clock() + timeout_s
        synced = False
        while True:
            if self.unread_bytes() == 0:
                if synced:
                    for entry in self._on_disk:
                        if entry[1] is None:
                            entry[1] = self._bytes_written
                    self.collect()
                    return True
                self._write(SYNC_LINE)
                synced = True
                continue
            if clock() >= deadline:
                return False
            sleep(SYNC_POLL_S)

    def write_frame(
        self,
        index: int,
        t_mono_s: float,
        rgb: np.ndarray,
        raw_disparity: np.ndarray,
        clock,
        accel: tuple[int, int, int] | None = None,
    ) -> tuple[float, str, str]:
        """Writes the files completely, then their INDEX lines: the accelerometer record first
        (`accel` counts, when given), then depth and colour. Returns (time just before the lines
        were written, depth file name, rgb file name). Call only after wait_reader_done()
        returned True (else the FIFO could queue frames and the stamps would be ambiguous)."""
        h, w = raw_disparity.shape
        ticks = int(t_mono_s * FAKENECT_TICKS_PER_S) & 0xFFFFFFFF
        dname = f"d-{FAKENECT_NO_PACING_TIME}-{ticks}-{index}.pgm"
        rname = f"r-{FAKENECT_NO_PACING_TIME}-{ticks}-{index}.ppm"
        files = [
            (dname, f"P5 {w} {h} 65535\n".encode(), raw_disparity.astype("=u2", copy=False)),
            (rname, f"P6 {w} {h} 255\n".encode(), rgb),
        ]
        names = [dname, rname]
        if accel is not None:
            aname = f"a-{FAKENECT_NO_PACING_TIME}-{ticks}-{index}.dump"
            files.insert(0, (aname, TILT_STATE.pack(*accel, 0, 0), np.zeros(0, np.uint8)))
            names.insert(0, aname)
        for name, header, data in files:
            tmp = self.dir / f".{name}.tmp"
            with open(tmp, "wb") as f:
                f.write(header)
                f.write(np.ascontiguousarray(data).data)
            os.replace(tmp, self.dir / name)
        written_s = clock()
        self.last_written_s = written_s
        self._write("".join(n + "\n" for n in names).encode())
        self._on_disk.append([[self.dir / n for n in names], None])
        return written_s, dname, rname

    def collect(self) -> None:
        """Deletes the files of frames fakenect is done with (a sync line after them was read)."""
        if self.keep_files or self._fd is None:
            return
        consumed = self._bytes_written - self.unread_bytes()
        while self._on_disk and self._on_disk[0][1] is not None and self._on_disk[0][1] <= consumed:
            for p in self._on_disk.pop(0)[0]:
                p.unlink(missing_ok=True)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # the reader sees EOF once it has read what is left
            self._fd = None


def _read_requests(fd: int, buf: bytearray, block: bool) -> list[tuple] | None:
    """Whole request messages from the pipe: waits for one if `block`, then takes what is there.
    None at EOF (the parent went away)."""
    import select

    while True:
        ready, _, _ = select.select([fd], [], [], None if block and len(buf) < _REQUEST.size else 0)
        if not ready:
            break
        chunk = os.read(fd, 64 * _REQUEST.size)
        if not chunk:
            return None
        buf += chunk
        if len(buf) >= _REQUEST.size:
            block = False
    n = len(buf) // _REQUEST.size
    out = [_REQUEST.unpack_from(buf, k * _REQUEST.size) for k in range(n)]
    del buf[: n * _REQUEST.size]
    return out


def _child_main() -> int:
    """Renderer child (`python -m kinect_emulator.live_child`): stdin carries a length-prefixed
    pickle of the configuration, then fixed-size requests; it answers "ready" on stdout once the
    FIFO is open, then renders the newest request, writes it and records it, until the stop
    request."""
    import pickle
    import sys

    fd = sys.stdin.fileno()
    head = b""
    while len(head) < 8:
        chunk = os.read(fd, 8 - len(head))
        if not chunk:
            return 1
        head += chunk
    size = struct.unpack("<Q", head)[0]
    blob = bytearray()
    while len(blob) < size:
        chunk = os.read(fd, min(1 << 20, size - len(blob)))
        if not chunk:
            return 1
        blob += chunk
    dump_dir, options, room, keep_files = pickle.loads(bytes(blob))
    emu = KinectEmulator(room if room is not None else default_room(), options)
    # mm -> raw disparity for every uint16 value: bit-identical to depth_mm_to_freenect_raw.
    lut = depth_mm_to_freenect_raw(np.arange(1 << 16, dtype=np.uint16))
    index = FakenectFifoIndex(dump_dir, keep_files)
    index.open()
    records = open(Path(dump_dir) / RECORDS_NAME, "a", encoding="utf-8")
    sys.stdout.write(f"ready {emu.renderer}\n")  # which back end renders (cpp | numpy)
    sys.stdout.flush()
    buf = bytearray()
    n_rendered = 0
    # Truth positions of every request (superseded ones too): the camera's acceleration for the
    # accelerometer record. Its noise: a generator of its own, seeded by the options.
    history: list[tuple[float, np.ndarray]] = []
    accel_rng = np.random.default_rng([options.seed, ACCEL_NOISE_STREAM])
    try:
        while True:
            reqs = _read_requests(fd, buf, block=True)
            if reqs is None or any(r[0] == _STOP_SEQ for r in reqs):
                return 0
            for _, t_r, *flat_r in reqs:
                history = history[1 - ACCEL_FIT_SAMPLES :] + [
                    (t_r, np.array(flat_r).reshape(4, 4)[:3, 3])
                ]
            seq, t_s, *flat = reqs[-1]
            start = time.monotonic()
            rec = {
                "index": n_rendered,
                "seq": seq,
                "t_mono_s": t_s,
                "T_room_cam": flat,
                "superseded": len(reqs) - 1,
                "render_start_mono_s": start,
            }
            if index.reader_is_behind() and start - index.last_written_s > READER_STALLED_S:
                # The streamer has not read the previous frame for a while (not started, stopped or
                # stalled): a render now could not be written; save the CPU for the rig.
                rec.update(index=None, delivered=False, skipped=True, render_end_mono_s=start)
                records.write(json.dumps(rec) + "\n")
                records.flush()
                continue
            try:
                frame = emu.render_indexed(
                    np.array(flat).reshape(4, 4), int(round(t_s * 1e6)), n_rendered
                )
            except ValueError as e:  # e.g. a pose outside the room: no frame, the camera goes on
                rec.update(error=str(e), delivered=False, render_end_mono_s=time.monotonic())
            else:
                rec["render_end_mono_s"] = time.monotonic()
                # The sensor's exposure -> USB delay (options.latency_ms): a real frame reaches the
                # host no earlier than that after its exposure (the request time t_s).
                hold_s = t_s + options.latency_ms / 1e3 - time.monotonic()
                if hold_s > 0:
                    time.sleep(hold_s)
                if not index.wait_reader_done(time.monotonic, time.sleep, FAKENECT_WAIT_S):
                    rec["delivered"] = False
                else:
                    T = np.array(flat).reshape(4, 4)
                    counts = accel_counts(
                        T,
                        acceleration_from_poses(history),
                        accel_rng.normal(0.0, ACCEL_NOISE_MPS2, 3),
                    )
                    written, dname, rname = index.write_frame(
                        n_rendered, t_s, frame.rgb, lut[frame.depth_mm], time.monotonic, counts
                    )
                    rec.update(
                        delivered=True,
                        index_written_mono_s=written,
                        depth_file=dname,
                        rgb_file=rname,
                        accel_counts=list(counts),
                    )
            n_rendered += 1
            records.write(json.dumps(rec) + "\n")
            records.flush()
    finally:
        index.close()
        records.close()


class LiveKinect:
    """A Kinect v1 that renders live from submitted poses into a fakenect FIFO dump (see module)."""

    def __init__(
        self,
        dump_dir,
        options: KinectOptions | None = None,
        room: Room | None = None,
        keep_files: bool = False,
    ) -> None:
        """dump_dir: created by start(); must not hold an offline dump (a regular INDEX.txt).
        room: None = default_room() built in the child (saves pickling the textures)."""
        self.dir = Path(dump_dir)
        self.options = options or KinectOptions()
        self.options.validate()
        self.room = room
        self.keep_files = keep_files
        self._proc = None
        self.renderer = "numpy"  # the child's back end, "cpp" | "numpy", known after start()
        self._tx = None
        self._tx_lock = threading.Lock()  # submit(): never held for more than a pipe write
        self._rec_lock = threading.Lock()  # records(), stats()
        self._seq = 0
        self._send_failed = 0
        self._records: list[LiveFrameRecord] = []
        self._undelivered: list[dict] = []
        self._records_offset = 0
        self._partial = b""

    # ---- life cycle ------------------------------------------------------------------------------
    def start(self) -> None:
        """Creates dump_dir and the INDEX.txt FIFO, starts the renderer child and waits until it
        holds the FIFO open. Start the streamer after this: started before, fakenect finds no
        INDEX.txt and exits ("Cannot open file")."""
        if self._proc is not None:
            raise RuntimeError("LiveKinect already started")
        self.dir.mkdir(parents=True, exist_ok=True)
        idx = self.dir / INDEX_NAME
        if idx.exists() or idx.is_symlink():
            if not stat.S_ISFIFO(idx.lstat().st_mode):
                raise FileExistsError(f"{idx} is an offline dump's index, not a live FIFO")
            idx.unlink()
        os.mkfifo(idx)
        (self.dir / RECORDS_NAME).write_text("")
        import pickle
        import select
        import sys

        # the renderer's camera model (protocol/camera): the child needs it too
        import rgbd_protocol

        env = dict(os.environ)
        pkg_parent = str(Path(__file__).resolve().parents[1])
        pkg_parent += os.pathsep + str(Path(rgbd_protocol.__file__).resolve().parents[1])
        env["PYTHONPATH"] = pkg_parent + (
            os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else ""
        )
        # A subprocess, not multiprocessing: no re-import of the caller's __main__, own GIL.
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "kinect_emulator.live_child"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=env,
        )
        blob = pickle.dumps((str(self.dir), self.options, self.room, self.keep_files))
        try:
            self._proc.stdin.write(struct.pack("<Q", len(blob)) + blob)
            self._proc.stdin.flush()
        except BrokenPipeError:
            pass
        self._tx = self._proc.stdin.fileno()
        os.set_blocking(self._tx, False)  # submit() must never wait
        ready, _, _ = select.select([self._proc.stdout], [], [], START_TIMEOUT_S)
        line = self._proc.stdout.readline() if ready else b""
        words = line.split()
        if not words or words[0] != b"ready":
            code = self._proc.poll()
            self.close()
            raise RuntimeError(
                "live Kinect renderer did not start "
                + (f"(exit code {code})" if code is not None else f"within {START_TIMEOUT_S} s")
            )
        self.renderer = words[1].decode() if len(words) > 1 else "numpy"
        _log.info("live Kinect: %s renderer in the child (pid %d)", self.renderer, self._proc.pid)

    def alive(self) -> bool:
        """True while the renderer child runs (it exits on close() or on an unexpected error,
        which it prints on stderr; the streamer then sees the end of the dump)."""
        proc = self._proc
        return proc is not None and proc.poll() is None

    def streamer_command(self, streamer_bin, *args) -> list[str]:
        """The `fakenect` wrapper form: ["fakenect", dump_dir, streamer_bin, "--source", "freenect",
        "--freenect-disparity-depth", *args]. Note the wrapper is a bash script that does not exec:
        stopping it by PID leaves the streamer running; prefer direct_streamer_command()."""
        return ["fakenect", str(self.dir), *self.direct_streamer_command(streamer_bin, *args)]

    def direct_streamer_command(self, streamer_bin, *args) -> list[str]:
        """The streamer itself (its PID is the one to stop); run it with env=streamer_env()."""
        return [
            str(streamer_bin),
            "--source",
            "freenect",
            "--freenect-disparity-depth",
            *(str(a) for a in args),
        ]

    def streamer_config_yaml(self, extra: str = "") -> str:
        """rgbd-streamer settings for this camera: the renderer draws depth already registered to
        its RGB camera, so both intrinsics are the renderer's and the registration is identity.
        `extra`: more YAML lines appended as they are."""
        i = self.options.intrinsics
        k = f"[{i.fx}, {i.fy}, {i.cx}, {i.cy}]"
        return f"rgb_intrinsics: {k}\ndepth_intrinsics: {k}\nt_rgb_depth_m: [0, 0, 0]\n" + extra

    def streamer_env(self, base: dict | None = None) -> dict:
        """What the fakenect wrapper sets: FAKENECT_PATH and the fakenect library first on
        LD_LIBRARY_PATH. Raises FileNotFoundError when libfreenect-bin is not installed."""
        lib = fakenect_lib_dir()
        if lib is None:
            raise FileNotFoundError("fakenect library not found (install libfreenect-bin)")
        env = dict(os.environ if base is None else base)
        env["FAKENECT_PATH"] = str(self.dir)
        env["LD_LIBRARY_PATH"] = lib + (
            ":" + env["LD_LIBRARY_PATH"] if env.get("LD_LIBRARY_PATH") else ""
        )
        return env

    def close(self) -> None:
        """Stops the child (stop request, join, then SIGTERM/SIGKILL to its PID), which closes the
        FIFO (the streamer's libfreenect sees the end of the dump), and removes the FIFO. Records,
        and with keep_files the frames, stay. Idempotent."""
        with self._tx_lock:
            proc, self._proc = self._proc, None
            if proc is None:
                return
            try:
                os.set_blocking(self._tx, True)
                os.write(self._tx, _REQUEST.pack(_STOP_SEQ, 0.0, *([0.0] * 16)))
            except OSError:
                pass
        try:
            proc.wait(CLOSE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.terminate()  # this PID only
            try:
                proc.wait(CLOSE_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(CLOSE_TIMEOUT_S)
        for f in (proc.stdin, proc.stdout):
            try:
                f.close()
            except OSError:
                pass
        self.records()  # read the last lines
        (self.dir / INDEX_NAME).unlink(missing_ok=True)

    def __enter__(self) -> "LiveKinect":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- per frame -------------------------------------------------------------------------------
    def submit(self, t_mono_s: float, T_room_cam: np.ndarray) -> bool:
        """Requests a frame exposed at monotonic time t_mono_s from pose T_room_cam (4x4, maps
        camera points to room). Never blocks: if the child is busy the newest request replaces a
        waiting one. False if the request could not be handed over (child gone / not started).
        Raises ValueError for a non-finite time or a pose that is not a finite 4x4 matrix."""
        # Plain-Python checks: a few numpy calls on a 4x4 cost ~100 us on a cold cache here.
        T = T_room_cam if isinstance(T_room_cam, np.ndarray) else np.asarray(T_room_cam, float)
        try:
            vals = T.ravel().tolist()
            ok = T.shape == (4, 4) and all(map(math.isfinite, vals)) and math.isfinite(t_mono_s)
        except TypeError:
            ok = False
        if not ok:
            raise ValueError("submit needs a finite time and a finite 4x4 T_room_cam")
        with self._tx_lock:
            seq = self._seq
            self._seq += 1
            if self._proc is None:
                self._send_failed += 1
                return False
            try:
                # One write below PIPE_BUF: the child gets whole requests or nothing.
                os.write(self._tx, _REQUEST.pack(seq, float(t_mono_s), *vals))
            except (BlockingIOError, BrokenPipeError, OSError):
                self._send_failed += 1
                return False
        return True

    # ---- results ---------------------------------------------------------------------------------
    def records(self) -> list[LiveFrameRecord]:
        """Delivered frames so far (INDEX order), read from the child's records file."""
        with self._rec_lock:
            path = self.dir / RECORDS_NAME
            try:
                with open(path, "rb") as f:
                    f.seek(self._records_offset)
                    data = f.read()
            except FileNotFoundError:
                return list(self._records)
            self._records_offset += len(data)
            data = self._partial + data
            *lines, self._partial = data.split(b"\n")
            for line in lines:
                if not line:
                    continue
                d = json.loads(line)
                if not d.get("delivered"):
                    self._undelivered.append(d)
                    continue
                self._records.append(delivered_record(d))
            return list(self._records)

    def forget_before(self, t_mono_s: float) -> None:
        """Drops the records of frames exposed before t_mono_s (read so far from the child's
        records file; later ones are still read). A Kinect that lives for hours (the soak: 30 a
        second) calls it once the earlier frames have been scored; records() then starts there."""
        self.records()
        with self._rec_lock:
            self._records = [r for r in self._records if r.t_mono_s >= t_mono_s]

    def stats(self) -> dict:
        """renderer (back end), submitted, pending, rendered, delivered, dropped (= superseded +
        reader_behind + errors
        + send_failed; submitted = delivered + dropped + pending), render ms median/p95 (child, per
        rendered frame: ray cast, texture, noise; not the file writes)."""
        recs = self.records()
        with self._rec_lock:
            und = list(self._undelivered)
        with self._tx_lock:
            submitted, send_failed = self._seq, self._send_failed
        superseded = sum(r.superseded for r in recs) + sum(d["superseded"] for d in und)
        errors = sum(1 for d in und if "error" in d)
        skipped = sum(1 for d in und if d.get("skipped"))
        behind = len(und) - errors  # rendered but not written, or not rendered (skipped)
        ms = [1e3 * (r.render_end_mono_s - r.render_start_mono_s) for r in recs]
        ms += [
            1e3 * (d["render_end_mono_s"] - d["render_start_mono_s"])
            for d in und
            if "error" not in d and not d.get("skipped")
        ]
        served = len(recs) + len(und) + superseded + send_failed
        return {
            "submitted": submitted,
            "pending": submitted - served,  # waiting, or discarded with the stop request
            "rendered": len(recs) + behind - skipped,
            "delivered": len(recs),
            "superseded": superseded,
            "reader_behind": behind,
            "errors": errors,
            "send_failed": send_failed,
            "dropped": superseded + behind + errors + send_failed,
            "render_ms_median": float(np.median(ms)) if ms else math.nan,
            "render_ms_p95": float(np.percentile(ms, 95)) if ms else math.nan,
            "renderer": self.renderer,  # back end of the child: "cpp" | "numpy"
        }

    def error_messages(self) -> list[str]:
        """Why frames were not rendered (e.g. a pose outside the room), in order."""
        self.records()
        with self._rec_lock:
            return [d["error"] for d in self._undelivered if "error" in d]
