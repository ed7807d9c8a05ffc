"""hilrig.machine_lock: one real-time HIL flight per machine."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from hilrig.machine_lock import FlightLock, FlightLockTimeout

HOLD = """
import sys, time
sys.path.insert(0, {hil!r})
from hilrig.machine_lock import FlightLock
lock = FlightLock({path!r}, say=lambda m: None).acquire("holder flight")
print("held", flush=True)
time.sleep({hold_s})
"""


def _holder(tmp_path, hold_s: float) -> subprocess.Popen:
    from hilrig.paths import REPO_ROOT

    code = HOLD.format(hil=str(REPO_ROOT / "hil"), path=str(tmp_path / "lock"), hold_s=hold_s)
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "held"
    return p


def test_a_second_flight_waits_for_the_first_and_says_who_holds_it(tmp_path):
    # GIVEN another process holding the lock for ~1 s
    holder = _holder(tmp_path, 1.0)
    said: list[str] = []
    try:
        # WHEN this flight asks for it
        lock = FlightLock(tmp_path / "lock", wait_s_=30, say=said.append).acquire("second flight")
        # THEN it got it only after the holder ended, and said whom it waited for
        assert holder.poll() is not None
        assert lock.waited_s > 0.3
        assert said and "holder flight" in said[0] and f"pid {holder.pid}" in said[0]
        assert "second flight" in lock.holder()
        lock.release()
        lock.release()  # idempotent
    finally:
        holder.kill()
        holder.wait()


def test_a_flight_that_cannot_get_the_lock_in_time_fails_naming_the_holder(tmp_path):
    holder = _holder(tmp_path, 30.0)
    try:
        t0 = time.monotonic()
        with pytest.raises(FlightLockTimeout, match=f"pid {holder.pid}: holder flight"):
            FlightLock(tmp_path / "lock", wait_s_=0.6, say=lambda m: None).acquire("late flight")
        assert time.monotonic() - t0 < 10
    finally:
        holder.kill()
        holder.wait()


def test_a_killed_holder_leaves_no_stale_lock(tmp_path):
    # GIVEN a holder killed without releasing (a crashed flight)
    holder = _holder(tmp_path, 30.0)
    holder.kill()
    holder.wait()
    # THEN the kernel released its flock: the next flight starts at once
    lock = FlightLock(tmp_path / "lock", wait_s_=0.5, say=lambda m: None).acquire("next flight")
    assert lock.waited_s < 0.5
    lock.release()
