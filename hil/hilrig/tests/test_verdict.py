"""`make demo`'s verdict (hilrig.verdict): every target passes or misses with a reason, SLAM map
resets are counted from what the processes logged and reported, a rig that fell behind says so."""

from hilrig.verdict import judge, map_resets

GOOD = {
    "hold": {"max_m": 0.12, "max_horizontal_m": 0.11, "max_vertical_m": 0.02},
    "waypoints": [{"max_m": 0.05}, {"max_m": 0.14}],
    "landing": {"touchdown_vertical_speed_mps": 0.29},
    "ate": {"ate_rmse_m": 0.012, "ate_max_m": 0.03},
    "stream": {
        "received_fps": 29.5,
        "kinect": {"submitted": 1000, "delivered": 980, "superseded": 20, "render_ms_median": 14.0},
    },
    "realtime_factor": 0.99,
}
SERVER_LOG_ONE_MAP = (
    "slam-server: client #1 connected from 127.0.0.1:5555\n"
    "slam-server: map 00000000000000ab started (new)\n"
)
QC_LOG_ONE_MAP = (
    "quad-control: SLAM link: connected to slam-server at x: map 00000000000000ab started (new)\n"
)


def by_target(checks):
    return {c.target: c for c in checks}


def test_given_a_good_flight_when_judged_then_every_target_passes():
    resets = map_resets(SERVER_LOG_ONE_MAP, QC_LOG_ONE_MAP, {"slam": {"sessions_started": 1}})
    assert resets["resets"] == 0
    checks = judge(GOOD, resets, 30.0)
    assert all(c.passed for c in checks), [c.line() for c in checks if not c.passed]
    assert set(by_target(checks)) == {
        "rig real-time",
        "hold",
        "waypoint 1",
        "waypoint 2",
        "touchdown",
        "SLAM ATE",
        "SLAM map resets",
    }


def test_given_misses_when_judged_then_each_says_which_and_why():
    bad = dict(
        GOOD,
        hold={"max_m": 0.2, "max_horizontal_m": 0.2, "max_vertical_m": 0.01},
        ate={"ate_rmse_m": 0.0792, "ate_max_m": 0.2},
        landing={"touchdown_vertical_speed_mps": 0.6},
    )
    checks = by_target(judge(bad, {"resets": 0}, 30.0))
    assert not checks["hold"].passed and "0.200 m from its hold point" in checks["hold"].why
    assert not checks["SLAM ATE"].passed and "79.2 mm" in checks["SLAM ATE"].why
    assert not checks["touchdown"].passed and "0.60 m/s" in checks["touchdown"].why
    assert checks["waypoint 2"].passed


def test_given_resets_in_the_old_log_format_then_they_are_counted():
    qc_log = "\n".join(
        ["quad-control: SLAM link: receive: End of file; reconnecting (a new SLAM session)"] * 3
    )
    server_log = "slam-server: client connected\n" * 4
    resets = map_resets(server_log, qc_log, None)
    assert resets["resets"] == 3
    check = by_target(judge(GOOD, resets, 30.0))["SLAM map resets"]
    assert not check.passed and "3 new map(s)" in check.why


def test_given_resumed_link_breaks_then_no_reset_is_counted():
    server_log = SERVER_LOG_ONE_MAP + (
        "slam-server: client #1 (127.0.0.1:5555) closed: "
        "peer closed the connection (end of file); 10 frames\n"
        "slam-server: map 00000000000000ab resumed "
        "(world frame kept, 10 frames, parked 3 ms)\n"
    )
    qc_log = QC_LOG_ONE_MAP + (
        "quad-control: SLAM link: disconnected: no PoseUpdate for frame 9 within 5000 ms; "
        "reconnecting to resume map 00000000000000ab (slam-server keeps it for a grace period)\n"
        "quad-control: SLAM link: connected to x: map 00000000000000ab resumed "
        "(world frame kept, 10 frames)\n"
    )
    resets = map_resets(server_log, qc_log, {"slam": {"sessions_started": 1}})
    assert resets["resets"] == 0 and resets["link_breaks"] == 1 and resets["resumes"] == 1


def test_given_a_new_map_after_a_link_break_then_one_reset_is_counted_from_each_log():
    # GIVEN a flight whose link broke and whose reconnect got a new map (the grace had run out)
    server_log = SERVER_LOG_ONE_MAP + (
        "slam-server: map 00000000000000ab ended (no client for 30000 ms): 10 frames\n"
        "slam-server: map 00000000000000ab started (new)\n"
    )
    qc_log = QC_LOG_ONE_MAP + (
        "quad-control: SLAM link: connected to x: map 00000000000000ab started "
        "(new, new world frame: SLAM map reset #1)\n"
    )
    # WHEN the resets are counted THEN both logs count one, and nothing was resumed
    resets = map_resets(server_log, qc_log, None)
    assert resets["sources"] == {"slam-server log": 1, "quad-control log": 1}
    assert resets["resets"] == 1 and resets["resumes"] == 0


def test_given_no_observation_then_resets_miss():
    check = by_target(judge(GOOD, map_resets(None, None, None), 30.0))["SLAM map resets"]
    assert not check.passed and "no log or state" in check.why


def test_given_an_overloaded_rig_then_it_says_so():
    slow = dict(
        GOOD,
        stream={
            "received_fps": 14,
            "kinect": {
                "submitted": 1000,
                "delivered": 500,
                "superseded": 500,
                "render_ms_median": 45,
            },
        },
    )
    check = by_target(judge(slow, {"resets": 0}, 30.0))["rig real-time"]
    assert not check.passed and "rig overloaded" in check.why and "500 superseded" in check.why


def test_given_an_aborted_flight_then_unmeasured_targets_miss():
    aborted = {
        "aborted": "arrival at (1.0, 0.0): not within 60 s",
        "ate": {"error": "only 2 tracked frames"},
    }
    checks = by_target(judge(aborted, {"resets": 0}, 30.0))
    assert not checks["flight completed"].passed
    assert (
        not checks["hold"].passed
        and not checks["waypoint 1"].passed
        and not checks["touchdown"].passed
    )
    assert "only 2 tracked frames" in checks["SLAM ATE"].why
    landed = by_target(judge(dict(aborted, touchdowns_mps=[0.2, 0.48]), {"resets": 0}, 30.0))
    assert landed["touchdown"].passed and landed["touchdown"].measured == "0.48 m/s"


def test_hold_only_flight_is_judged_on_rig_hold_ate_and_resets():
    from hilrig.verdict import judge_hold

    report = {k: v for k, v in GOOD.items() if k not in ("waypoints", "landing")}
    checks = judge_hold(report, {"resets": 0, "sources": {"slam-server log": 0}}, 30.0)
    assert [c.target for c in checks] == [
        "rig real-time",
        "hold",
        "SLAM ATE",
        "SLAM map resets",
    ]
    assert all(c.passed for c in checks)
    loaded = dict(
        report,
        stream={
            "received_fps": 12.0,
            "kinect": {
                "submitted": 1000,
                "delivered": 500,
                "superseded": 500,
                "render_ms_median": 60.0,
            },
        },
    )
    rig = judge_hold(loaded, {"resets": 0}, 30.0)[0]
    assert not rig.passed and "rig overloaded" in rig.why
    aborted = judge_hold(
        dict(report, aborted="take-off -> hold: not within 60 s", hold=None), {"resets": 1}, 30.0
    )
    assert [c.target for c in aborted if not c.passed] == [
        "flight completed",
        "hold",
        "SLAM map resets",
    ]
