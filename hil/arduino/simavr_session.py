"""Python driver of fw_sim, the libsimavr harness that runs the REAL firmware image.

A Scenario collects timed inputs (bridge requests, raw bridge bytes, MAVLink telemetry bytes), runs
the firmware under simavr once, deterministically, and returns what was observable on the wire:
every RC pulse (channel, rise time, width), every request sent and every reply line, all in
simulated microseconds. The HIL rig builds on this.

    sc = Scenario()
    sc.req(20_000, build_control_request(key, 1, True, 1500, 1500, 1000, 1500))
    sc.end(200_000)
    result = sc.run(key_record=record_bytes)
    result.pulses_of(3)          # throttle pulses

This is the one driver of fw_sim: the HIL rig's live flights (LiveSession) and the batch scenarios
(Scenario) both go through it. The harness is found at $RGBD_BUILD_DIR/bin/fw_sim (default
<repo>/build, `make build`), the image at $RGBD_FIRMWARE_ELF (default
firmware/.pio/build/uno_wifi/program.elf, `make firmware`); both can also be passed explicitly.
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field

from hilrig.paths import find_binary

REPO = pathlib.Path(__file__).resolve().parents[2]
#: Upper bound on one fw_sim run (wall clock): scenarios are a few simulated seconds, simavr runs
#: ~3.7x faster than real time, so anything near this is a hang.
RUN_TIMEOUT_S = 120
#: One 8N1 byte on the 57600-baud telemetry wire (the rate fw_sim drives the pin at).
MAV_BYTE_US = 10 / 57600 * 1e6


FIRMWARE_ELF = REPO / "firmware" / ".pio" / "build" / "uno_wifi" / "program.elf"


def fw_sim_path() -> pathlib.Path:
    """Where the harness should be ($RGBD_BUILD_DIR/bin/fw_sim), built or not."""
    found = find_binary("fw_sim")
    if found is not None:
        return found
    return pathlib.Path(os.environ.get("RGBD_BUILD_DIR", REPO / "build")) / "bin" / "fw_sim"


def firmware_elf_path() -> pathlib.Path:
    """Where the firmware image should be ($RGBD_FIRMWARE_ELF), built or not."""
    return pathlib.Path(os.environ.get("RGBD_FIRMWARE_ELF", FIRMWARE_ELF))


def firmware_elf() -> pathlib.Path | None:
    """The firmware image if it is built, else None."""
    p = firmware_elf_path()
    return p if p.is_file() else None


def _require(
    sim: pathlib.Path | None, elf: pathlib.Path | None
) -> tuple[pathlib.Path, pathlib.Path]:
    sim, elf = sim or fw_sim_path(), elf or firmware_elf_path()
    for p, how in (
        (sim, "build it: make build (or cmake --build ... --target fw_sim)"),
        (elf, "build it: make firmware (firmware/build.sh)"),
    ):
        if not p.is_file():
            raise FileNotFoundError(f"{p} not found: {how}")
    return sim, elf


@dataclass(frozen=True)
class Pulse:
    channel: int  # 1..4 (roll, pitch, throttle, yaw)
    rise_us: float
    width_us: float

    @property
    def end_us(self) -> float:
        return self.rise_us + self.width_us

    @property
    def rc_index(self) -> int:
        """0..3, the index the flight-controller emulator's feed_pulse takes."""
        return self.channel - 1


@dataclass(frozen=True)
class Reply:
    start_us: float
    end_us: float
    text: str


@dataclass(frozen=True)
class Sent:
    start_us: float
    end_us: float


@dataclass
class Result:
    pulses: list[Pulse] = field(default_factory=list)
    replies: list[Reply] = field(default_factory=list)
    sent: list[Sent] = field(default_factory=list)
    done_us: float = 0.0
    eeprom: bytes | None = (
        None  # the EEPROM at the end (1024 bytes), when run(..., keep_eeprom=True)
    )
    stack_free: int | None = (
        None  # SRAM bytes above .bss never written, when run(..., stack_paint_from=)
    )

    def pulses_of(
        self, channel: int, after_us: float = 0.0, before_us: float = float("inf")
    ) -> list[Pulse]:
        return [
            p for p in self.pulses if p.channel == channel and after_us <= p.rise_us < before_us
        ]

    def frame_at(self, t_us: float) -> list[float]:
        """Widths of the four channels in the first complete frame starting at or after t_us."""
        out = []
        for ch in range(1, 5):
            later = self.pulses_of(ch, after_us=t_us)
            if not later:
                raise ValueError(f"no pulse on channel {ch} after {t_us} us")
            out.append(later[0].width_us)
        return out


class Scenario:
    """Timed inputs for one simulated run (times in simulated microseconds from reset)."""

    def __init__(self) -> None:
        self._lines: list[str] = []
        self._end_us: float | None = None

    def req(self, t_us: float, line: str) -> None:
        """A bridge request line, sent at t_us or once the previous reply has arrived."""
        if "\n" in line:
            raise ValueError("request lines must not contain newlines (use raw())")
        self._lines.append(f"req {t_us:.3f} {line}")

    def raw(self, t_us: float, data: bytes) -> None:
        """Raw bytes on the bridge UART at t_us (no reply awaited)."""
        self._lines.append(f"raw {t_us:.3f} {data.hex()}")

    def mav(self, t_us: float, data: bytes) -> None:
        """Bytes on the MAVLink telemetry pin as 57600-baud serial from t_us, or right after the
        previous burst when that one is still on the wire (fw_sim queues them like a UART)."""
        self._lines.append(f"mav {t_us:.3f} {data.hex()}")

    def end(self, t_us: float) -> None:
        self._end_us = t_us

    def script(self) -> str:
        if self._end_us is None:
            raise ValueError("call end(t_us) first")
        return "\n".join(self._lines + [f"end {self._end_us:.3f}"]) + "\n"

    def run(
        self,
        key_record: bytes | None,
        workdir: pathlib.Path | None = None,
        keep_eeprom: bool = False,
        stack_paint_from: int | None = None,
        fw_sim: pathlib.Path | None = None,
        elf: pathlib.Path | None = None,
        timeout_s: float = RUN_TIMEOUT_S,
        bridge_byte_us: float | None = None,
    ) -> Result:
        """Runs fw_sim; key_record is the EEPROM content from address 0 (None: erased EEPROM, no
        key), e.g. a key record or the `eeprom` of an earlier Result (a reboot). bridge_byte_us:
        period of the bridge bytes (None: fw_sim's default, simavr's 16 us; at least 16)."""
        sim, elf = _require(fw_sim, elf)
        with tempfile.TemporaryDirectory(dir=workdir) as tmp:
            # A private copy of the image: the one in the tree can be rebuilt while this runs.
            elf_copy = pathlib.Path(tmp) / "program.elf"
            shutil.copyfile(elf, elf_copy)
            args = [str(sim), "--elf", str(elf_copy)]
            if key_record is not None:
                ee = pathlib.Path(tmp) / "eeprom_in.bin"
                ee.write_bytes(key_record)
                args += ["--eeprom", str(ee)]
            ee_out = pathlib.Path(tmp) / "eeprom_out.bin"
            if keep_eeprom:
                args += ["--eeprom-out", str(ee_out)]
            if stack_paint_from is not None:
                args += ["--stack-paint", hex(stack_paint_from)]
            if bridge_byte_us is not None:
                args += ["--bridge-byte-us", f"{bridge_byte_us:g}"]
            proc = subprocess.run(
                args,
                input=self.script(),
                capture_output=True,
                text=True,
                timeout=timeout_s,
                check=False,
            )
            if proc.returncode != 0:
                raise RuntimeError(f"fw_sim failed ({proc.returncode}): {proc.stderr.strip()}")
            result = parse_log(proc.stdout)
            if keep_eeprom:
                result.eeprom = ee_out.read_bytes()
        return result


def parse_log(text: str) -> Result:
    r = Result()
    for line in text.splitlines():
        kind, _, rest = line.partition(" ")
        if kind == "pulse":
            ch, rise, width = rest.split()
            r.pulses.append(Pulse(int(ch), float(rise), float(width)))
        elif kind == "reply":
            start, end, body = rest.split(" ", 2)
            r.replies.append(Reply(float(start), float(end), body))
        elif kind == "sent":
            start, end = rest.split()
            r.sent.append(Sent(float(start), float(end)))
        elif kind == "done":
            r.done_us = float(rest)
        elif kind == "stack_free":
            r.stack_free = int(rest)
    return r


class LiveSession:
    """Lock-step co-simulation with the firmware (fw_sim --interactive).

    The caller advances simulated time with run(t_us) and gets the pulses, requests sent and replies
    produced up to t_us, so a flight-controller model or a ground-station loop can react to them
    before feeding the next inputs (closed loop, still deterministic: no wall clock involved).
    Use as a context manager; the fw_sim process is stopped by its PID on exit.
    """

    def __init__(
        self,
        key_record: bytes | None,
        workdir: pathlib.Path | None = None,
        fw_sim: pathlib.Path | None = None,
        elf: pathlib.Path | None = None,
    ) -> None:
        sim, elf = _require(fw_sim, elf)
        args = [str(sim), "--elf", str(elf), "--interactive"]
        self._eeprom = None
        if key_record is not None:
            wd = workdir or pathlib.Path(os.environ.get("TMPDIR", "/tmp"))
            self._eeprom = wd / f"fw_sim_live_eeprom_{os.getpid()}_{id(self)}.bin"
            self._eeprom.write_bytes(key_record)
            args += ["--eeprom", str(self._eeprom)]
        # stderr to a file, not a pipe: nobody reads it while the session runs, so a pipe could
        # fill.
        self._stderr = tempfile.TemporaryFile(mode="w+")
        self._proc = subprocess.Popen(
            args,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            text=True,
            bufsize=1,
        )
        self.now_us = 0.0

    def _send(self, line: str) -> None:
        assert self._proc.stdin is not None
        self._proc.stdin.write(line + "\n")

    def req(self, t_us: float, line: str) -> None:
        if "\n" in line:
            raise ValueError("request lines must not contain newlines")
        self._send(f"req {max(t_us, self.now_us):.3f} {line}")

    def raw(self, t_us: float, data: bytes) -> None:
        self._send(f"raw {max(t_us, self.now_us):.3f} {data.hex()}")

    def mav(self, t_us: float, data: bytes) -> None:
        self._send(f"mav {max(t_us, self.now_us):.3f} {data.hex()}")

    def run(self, t_us: float) -> Result:
        """Simulates up to t_us and returns what happened since the previous run()."""
        self._send(f"run {t_us:.3f}")
        assert self._proc.stdin is not None and self._proc.stdout is not None
        self._proc.stdin.flush()
        lines = []
        while True:
            line = self._proc.stdout.readline()
            if not line:
                self._stderr.seek(0)
                raise RuntimeError(f"fw_sim ended unexpectedly: {self._stderr.read()[-2000:]}")
            if line.startswith("at "):
                self.now_us = float(line.split()[1])
                break
            lines.append(line)
        return parse_log("".join(lines))

    def close(self) -> None:
        if self._proc.poll() is None:
            try:
                self._send(f"end {self.now_us:.3f}")
                self._proc.stdin.close()  # type: ignore[union-attr]
                self._proc.wait(timeout=10)
            except (OSError, subprocess.TimeoutExpired):
                self._proc.kill()  # by PID (Popen keeps it), never by name
                self._proc.wait()
        self._stderr.close()
        if self._eeprom is not None:
            self._eeprom.unlink(missing_ok=True)

    def __enter__(self) -> LiveSession:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
