"""Per-thread CPU accounting (hilrig.thread_cpu): parsing, summing by name, a live process."""

import os
import threading
import time

from hilrig import thread_cpu


def test_parse_stat_counts_fields_after_the_last_parenthesis():
    # comm with a space and a parenthesis, as /proc prints it; utime 150, stime 50 ticks
    rest = "S 1 1 1 0 -1 4194560 100 0 0 0 150 50 0 0 20 0 3 0 100 1000 10"
    comm, cpu_s = thread_cpu.parse_stat(f"4242 (qc (a) b) {rest}\n")
    assert comm == "qc (a) b"
    assert cpu_s == (150 + 50) / thread_cpu.CLOCK_TICKS_PER_S


def test_threads_of_one_name_are_summed_and_unreadable_ones_skipped(tmp_path):
    task = tmp_path / "7" / "task"
    rest = "S 1 1 1 0 -1 0 0 0 0 0 {u} {s} 0 0 20 0 1 0 1 1 1"
    for tid, comm, u, s in [(7, "main", 10, 0), (8, "rx-rgb", 100, 0), (9, "rx-rgb", 40, 20)]:
        (task / str(tid)).mkdir(parents=True)
        (task / str(tid) / "stat").write_text(f"{tid} ({comm}) " + rest.format(u=u, s=s))
    (task / "10").mkdir()  # a thread that exited between the listing and the read: no stat
    got = thread_cpu.thread_cpu_s(7, proc_root=tmp_path)
    tick = thread_cpu.CLOCK_TICKS_PER_S
    assert got == {"rx-rgb": round(160 / tick, 2), "main": round(10 / tick, 2)}
    assert list(got) == ["rx-rgb", "main"]  # busiest first
    assert thread_cpu.thread_cpu_s(99999, proc_root=tmp_path) == {}
    (tmp_path / "7" / "stat").write_text("7 (quad-control) " + rest.format(u=300, s=30))
    assert thread_cpu.process_cpu_s(7, proc_root=tmp_path) == 330 / tick


def test_a_named_busy_thread_of_this_process_is_seen():
    named, stop = threading.Event(), threading.Event()

    def spin():
        # Named through /proc, as the C++ threads are with pthread_setname_np.
        with open(f"/proc/self/task/{threading.get_native_id()}/comm", "w") as comm:
            comm.write("hil-spin")
        named.set()
        while not stop.is_set():
            pass

    t = threading.Thread(target=spin)
    t.start()
    try:
        assert named.wait(5)
        deadline = time.monotonic() + 10
        got = {}
        while time.monotonic() < deadline and got.get("hil-spin", 0) <= 0:
            time.sleep(0.1)
            got = thread_cpu.thread_cpu_s(os.getpid())
        assert got.get("hil-spin", 0) > 0, got
    finally:
        stop.set()
        t.join()
