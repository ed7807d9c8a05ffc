"""firmware/tools/fw_limits.py (how tests outside the firmware read its constants) against the
compiler: the host C++ compiler builds a program that prints every constant of
firmware/core/limits.h, and the reader must find the same names with the same values, so a constant
the reader cannot see or misreads fails here instead of silently feeding a test a wrong timing."""

import pathlib
import re
import shutil
import subprocess

import fw_limits
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _compiled_values(tmp_path, names):
    cxx = shutil.which("g++") or shutil.which("c++")
    if cxx is None:
        pytest.fail("no host C++ compiler (make deps installs g++)")
    src = tmp_path / "print_limits.cpp"
    body = "\n".join(
        f'  std::printf("{n} %llu\\n", static_cast<unsigned long long>(fw::{n}));' for n in names
    )
    src.write_text(
        f'#include <cstdio>\n#include "limits.h"\nint main() {{\n{body}\n  return 0;\n}}\n'
    )
    exe = tmp_path / "print_limits"
    subprocess.run(
        [
            cxx,
            "-std=c++14",
            f"-I{ROOT / 'firmware' / 'core'}",
            f"-I{ROOT / 'protocol' / 'control' / 'include'}",
            str(src),
            "-o",
            str(exe),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    return {name: int(value) for name, value in (line.split() for line in out.splitlines())}


def test_reader_sees_every_constant_of_limits_h():
    # Every constexpr line of the header is a definition the reader took (none skipped by its
    # regex).
    text = fw_limits.LIMITS_H.read_text()
    declared = re.findall(r"^\s*constexpr\s+\w+\s+(k\w+)", text, re.M)
    assert declared and list(fw_limits.FW_LIMITS) == declared


def test_reader_values_match_the_compiler(tmp_path):
    names = list(fw_limits.FW_LIMITS)
    assert _compiled_values(tmp_path, names) == fw_limits.FW_LIMITS


def test_failsafe_timings_tests_rely_on():
    # The hand-over contract the simavr and HIL failsafe tests check (docs/failsafe.md): a failsafe
    # throttle below ArduCopter's FS_THR_VALUE and above its no-signal floor.
    lim = fw_limits.FW_LIMITS
    assert lim["kApmRcPulseMinValidUs"] < lim["kFailsafeThrottleUs"] < lim["kApmFsThrValueUs"]
    assert (
        lim["kApmLandHandoverMs"] == lim["kApmFsCounterFrames"] * lim["kPwmFramePeriodUs"] // 1000
    )
