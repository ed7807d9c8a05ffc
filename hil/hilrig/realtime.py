"""Scheduling of the HIL rig: the emulated hardware must keep real time however busy the machine
is.

In a real flight the FC, the firmware, the Kinect and the craft's onboard computer (rgbd-streamer)
have their own CPUs; here they share two cores with the ground station and everything else. So the
rig runs its threads and children under SCHED_RR at RIG_RT_PRIORITY, above the ground station's
CPU-heavy real-time threads (quad-control / slam-server "realtime" default SCHED_RR 10) and below
its firmware link thread (12: a hard 250 ms deadline, ~1 ms of CPU per command): the system
under test can then be slowed down by its neighbours (the load scenario's CPU burners, other
engineers' builds) but never the emulated hardware, unless the rig's own real-time work no longer
fits the cores - which the rig measures and reports as "rig overloaded"
(hilrig.verdict.rig_health).

Linux schedules threads individually and a thread or child inherits its creator's policy, so
`raise_this_thread()` is called on the thread that then creates the rig's threads and children
(SlamFlight.start); the ground station's processes are started through `normal_policy_argv()`
(`chrt --other 0`: back to SCHED_OTHER before exec) and raise their own real-time threads, as they
would on their own machine. Where the OS refuses (no CAP_SYS_NICE, no real-time bandwidth), the
fallback is nice -10, else nothing; either way the reason is returned for the flight's report.
"""

from __future__ import annotations

import os
import shutil

# Above the ground station's CPU-heavy real-time threads (frame, SLAM link, slam-server's tracking:
# SCHED_RR 10, quad-control.json "realtime"), below quad-control's firmware link thread (10 + 2,
# ground_station.cpp kCommandPriorityStep) and the kernel's threaded interrupt handlers (50).
# Not above the link thread (at 20, during the 10-minute flight): the rig's own bursts (renderer,
# rgbd-streamer, simavr, this process) filled both cores for 85 ms at a time and left the link
# thread runnable but without a CPU while the simulated firmware's 250 ms failsafe kept counting;
# two rigs on the machine stalled it 1.1 s and the failsafe landed the craft. On the craft, the
# firmware and camera have their own CPUs and never take the ground station's; the link thread
# needs ~1 ms of CPU per command (<1 % of a core), so ranking it above the rig costs the rig
# nothing.
RIG_RT_PRIORITY = 11
# When real-time is refused: a nice-0 neighbour then gets ~1/10 of the weight (CFS, 1.25x per step).
RIG_FALLBACK_NICE = -10


def _policy_name(policy: int) -> str:
    return {
        os.SCHED_OTHER: "SCHED_OTHER",
        os.SCHED_RR: "SCHED_RR",
        os.SCHED_FIFO: "SCHED_FIFO",
    }.get(policy, str(policy))


def current_policy() -> str:
    """This thread's policy and priority/nice, e.g. 'SCHED_RR 20' or 'SCHED_OTHER nice 0'."""
    policy = os.sched_getscheduler(0)
    if policy in (os.SCHED_RR, os.SCHED_FIFO):
        return f"{_policy_name(policy)} {os.sched_getparam(0).sched_priority}"
    return f"{_policy_name(policy)} nice {os.getpriority(os.PRIO_PROCESS, 0)}"


def raise_this_thread(
    priority: int = RIG_RT_PRIORITY, fallback_nice: int = RIG_FALLBACK_NICE
) -> str:
    """SCHED_RR at `priority` for the calling thread (pid 0 = the calling thread on Linux), else
    nice `fallback_nice`; returns what was applied and, on a fallback, why."""
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(priority))
        return f"SCHED_RR {priority}"
    except OSError as e:
        reason = f"real-time refused ({e.strerror})"
    try:
        os.setpriority(os.PRIO_PROCESS, 0, fallback_nice)
        return f"nice {fallback_nice} ({reason})"
    except OSError as e:
        return f"unchanged ({reason}; nice {fallback_nice} refused: {e.strerror})"


def restore_this_thread(saved: tuple[int, int, int]) -> None:
    """Puts the calling thread back to `saved` (from `save_this_thread`); best effort."""
    policy, prio, nice = saved
    try:
        os.sched_setscheduler(0, policy, os.sched_param(prio))
        if policy not in (os.SCHED_RR, os.SCHED_FIFO):
            os.setpriority(os.PRIO_PROCESS, 0, nice)
    except OSError:
        pass  # lowering is always allowed; raising back to a negative nice may not be


def save_this_thread() -> tuple[int, int, int]:
    return (
        os.sched_getscheduler(0),
        os.sched_getparam(0).sched_priority,
        os.getpriority(os.PRIO_PROCESS, 0),
    )


def normal_policy_argv(argv: list) -> list:
    """`argv` started under SCHED_OTHER at nice 0 whatever its parent runs under (util-linux chrt),
    for the processes of the system under test and the load; unchanged when chrt is missing (then
    they inherit the parent's policy, which the caller reports)."""
    chrt = shutil.which("chrt")
    return [chrt, "--other", "0", *argv] if chrt else list(argv)
