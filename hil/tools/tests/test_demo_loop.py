"""hil/tools/demo_loop.py's summary over several `make demo` reports (no flight flown here)."""

import importlib.util
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "demo_loop", Path(__file__).resolve().parents[1] / "demo_loop.py"
)
demo_loop = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(demo_loop)


def _report(c2p_ms, ate_m, resets, missed=()):
    return {
        "latency_ms": {"capture_to_pwm": {"median_ms": c2p_ms, "p95_ms": c2p_ms + 20}},
        "ate": {"ate_rmse_m": ate_m},
        "slam_link": {"resets": resets, "link_breaks": 0},
        "hold": {"max_m": 0.05},
        "verdict": [
            {"target": t, "passed": t not in missed} for t in ("hold", "SLAM ATE", *missed)
        ],
    }


def test_summary_counts_passes_resets_and_ranges():
    runs = [
        demo_loop.run_summary(1, 0, _report(55.0, 0.008, 0), "2.0 1.0 1.0", "2.5 1.0 1.0", 150.0),
        demo_loop.run_summary(
            2,
            1,
            _report(71.5, 0.041, 1, missed=("SLAM map resets",)),
            "4.5 3 2",
            "5 3 2",
            160.0,
        ),
        demo_loop.run_summary(3, 1, None, "3.0 2 2", "3 2 2", 5.0),  # the demo wrote no report
    ]
    s = demo_loop.summarise(runs)
    assert s["runs"] == 3 and s["passed"] == 1
    assert s["resets_total"] == 1 and s["resets_unobserved_runs"] == 1
    assert s["capture_to_pwm_median_ms_range"] == "55.0 .. 71.5"
    assert s["ate_mm_range"] == "8.0 .. 41.0"
    assert s["load_average_range"] == "2.0 .. 4.5"
    assert s["targets_missed"] == {"SLAM map resets": 1, demo_loop.NO_FLIGHT: 1}


def test_a_demo_that_fell_back_without_flying_is_not_a_pass():
    # hil/demo.sh exits 0 after the SLAM-only fallback when a part is missing (seen when a
    # concurrent
    # build was relinking quad-control): no report, so no flight to judge.
    r = demo_loop.run_summary(1, 0, None, "9.0 9 9", "9 9 9", 8.0)
    assert not r["passed"] and r["missed"] == [demo_loop.NO_FLIGHT]
