"""hil/tools/wind_table.py without flying: arguments, the failure rule, the lean-limit share, the
result figures and the table (the flights themselves run under `make hil`-like conditions only)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # hil/tools
import wind_table  # noqa: E402


def test_gust_and_law_arguments_are_checked():
    assert wind_table.parse_gusts("0.3,0,0.15,0.3") == [0.0, 0.15, 0.3]
    for bad in ("", "x", "-0.1", "nan", "9"):
        with pytest.raises(argparse.ArgumentTypeError):
            wind_table.parse_gusts(bad)
    assert wind_table.parse_laws("pid,cascade") == ["pid", "cascade"]
    with pytest.raises(argparse.ArgumentTypeError):
        wind_table.parse_laws("pid,lqr")


def test_bad_options_exit_with_a_usage_error(capsys):
    for argv in (["--hold-s", "1"], ["--fail-bound-m", "0.1"], ["--gusts", "a,b"]):
        with pytest.raises(SystemExit) as e:
            wind_table.main(argv)
        assert e.value.code == 2
    assert "error" in capsys.readouterr().err


@pytest.mark.parametrize(
    "flight, expected",
    [
        ({"hold": {"max_m": 0.12}, "state_after": "hold", "failsafe_events": []}, None),
        ({"hold": {"max_m": 0.61}, "state_after": "hold", "failsafe_events": []}, "hold 0.61 m"),
        ({"hold": {"max_m": 0.2}, "state_after": "land", "failsafe_events": []}, "left hold"),
        ({"hold": {"max_m": 0.2}, "state_after": "hold", "failsafe_events": ["x"]}, "failsafe"),
        ({"aborted": "take-off -> hold: not within 60 s"}, "mission aborted"),
    ],
)
def test_failure_rule(flight, expected):
    why = wind_table.failure(flight, 0.5)
    if expected is None:
        assert why is None
    else:
        assert why is not None and why.startswith(expected)


def test_lean_limit_share_counts_hold_commands_at_the_limit():
    # 20 % beyond the 20 us dead zone of 480 us: 116 us off neutral is the limit.
    rows = [
        {"state": "hold", "send_us": "10", "roll_us": "1616", "pitch_us": "1500"},  # at it
        {"state": "hold", "send_us": "11", "roll_us": "1500", "pitch_us": "1384"},  # at it
        {"state": "hold", "send_us": "12", "roll_us": "1550", "pitch_us": "1460"},
        {"state": "hold", "send_us": "13", "roll_us": "1500", "pitch_us": "1500"},
        {"state": "take-off", "send_us": "14", "roll_us": "1616", "pitch_us": "1500"},
        {"state": "hold", "send_us": "5", "roll_us": "1616", "pitch_us": "1500"},  # before
    ]
    assert wind_table.saturated_share(rows, 10) == 0.5
    assert wind_table.saturated_share(rows, 100) is None


def test_figures_and_table_carry_every_flight():
    flights = [
        {
            "law": "cascade",
            "gust_mss": 0.15,
            "hold": {"max_m": 0.09, "rms_m": 0.04},
            "lean_limit_share": 0.0,
            "ate": {"ate_rmse_m": 0.005},
            "latency_ms": {"capture_to_pwm": {"p95_ms": 45.0}},
            "slam_tracking": {"lost": 0},
            "load_average": "2.0 2.0 2.0",
            "failure": None,
        },
        {"law": "pid", "gust_mss": 1.2, "aborted": "x", "failure": "mission aborted: x"},
    ]
    figs = wind_table.figures(flights, 30.0)
    hold = [f for f in figs if f["name"] == "hold max"]
    assert [f["verdict"] for f in hold] == ["PASS", None]
    assert any(f["name"].startswith("loop failed") and f["mode"] == "pid" for f in figs)
    table = wind_table.markdown(flights).splitlines()
    assert len(table) == 4
    assert "| cascade | 0.15 | 0.09 | 0.04 |" in table[2]
    assert table[3].endswith("mission aborted: x |")
