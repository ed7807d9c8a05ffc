"""Runs the real firmware image in simavr through hil/arduino's `fw_sim` harness.

fw_sim plays a script (bridge requests, raw bytes, MAVLink bytes on the telemetry pin, all at
simulated microsecond times) and logs every RC pulse and reply (format: hil/arduino/fw_sim.cpp).
This module writes that script from Python values and parses the log back. It is batch, not
interactive: valid for scenarios where the firmware's outputs do not depend on what the flight
controller sends back (the telemetry only fills the replies), which the scenarios check by running
the firmware twice, without and with the telemetry, and comparing the pulses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path
import shutil

from hilrig.paths import REPO_ROOT, find_binary
from hilrig.procs import ManagedProcess

FIRMWARE_ELF = REPO_ROOT / "firmware/.pio/build/uno_wifi/program.elf"


def firmware_elf() -> Path | None:
    p = Path(os.environ.get("RGBD_FIRMWARE_ELF", FIRMWARE_ELF))
    return p if p.is_file() else None


@dataclass(frozen=True)
class Pulse:
    channel: int  # 0..3 (roll, pitch, throttle, yaw)
    rise_us: float
    width_us: float

    @property
    def end_us(self) -> float:
        return self.rise_us + self.width_us


@dataclass(frozen=True)
class ReplyLine:
    start_us: float
    end_us: float
    text: str


@dataclass
class FwSimResult:
    pulses: list[Pulse] = field(default_factory=list)
    replies: list[ReplyLine] = field(default_factory=list)
    sent: list[tuple[float, float]] = field(default_factory=list)
    done_us: float | None = None
    wall_log: str = ""


@dataclass
class FwScript:
    lines: list[str] = field(default_factory=list)

    def request(self, t_us: float, text: str) -> None:
        if "\n" in text:
            raise ValueError("a request is one line")
        self.lines.append(f"req {t_us:.3f} {text}")

    def raw(self, t_us: float, data: bytes) -> None:
        self.lines.append(f"raw {t_us:.3f} {data.hex()}")

    def mavlink(self, t_us: float, data: bytes) -> None:
        self.lines.append(f"mav {t_us:.3f} {data.hex()}")

    def end(self, t_us: float) -> None:
        self.lines.append(f"end {t_us:.3f}")

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def parse_log(text: str) -> FwSimResult:
    r = FwSimResult()
    for ln in text.splitlines():
        parts = ln.split(" ", 3)
        if parts[0] == "pulse" and len(parts) == 4:
            r.pulses.append(Pulse(int(parts[1]) - 1, float(parts[2]), float(parts[3])))
        elif parts[0] == "reply" and len(parts) == 4:
            r.replies.append(ReplyLine(float(parts[1]), float(parts[2]), parts[3]))
        elif parts[0] == "sent" and len(parts) >= 3:
            r.sent.append((float(parts[1]), float(parts[2])))
        elif parts[0] == "done":
            r.done_us = float(parts[1])
    return r


def run_fw_sim(
    script: FwScript,
    eeprom: bytes | None,
    workdir: Path,
    timeout_s: float = 300.0,
    name: str = "fw_sim",
) -> FwSimResult:
    """Runs fw_sim on the script; raises RuntimeError with the harness's stderr if it fails."""
    binary = find_binary("fw_sim")
    elf = firmware_elf()
    if binary is None or elf is None:
        raise FileNotFoundError(
            "fw_sim or the firmware .elf is not built (make build / make firmware)"
        )
    workdir.mkdir(parents=True, exist_ok=True)
    # A private copy: the image in the tree can be rebuilt while the scenario runs.
    elf_copy = workdir / "program.elf"
    shutil.copyfile(elf, elf_copy)
    script_path = workdir / f"{name}.script"
    script_path.write_text(script.text())
    argv = [binary, "--elf", elf_copy]
    if eeprom is not None:
        (workdir / "eeprom.bin").write_bytes(eeprom)
        argv += ["--eeprom", workdir / "eeprom.bin"]
    proc = ManagedProcess(
        argv,
        workdir / f"{name}.log",
        stdin_path=script_path,
        stderr_path=workdir / f"{name}.stderr",
    )
    try:
        rc = proc.wait(timeout_s)
    finally:
        proc.stop()
    if rc != 0:
        raise RuntimeError(
            f"fw_sim exited {rc}: {(workdir / f'{name}.stderr').read_text()[-2000:]}"
        )
    return parse_log((workdir / f"{name}.log").read_text())
