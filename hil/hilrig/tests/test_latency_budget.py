"""latency_budget: prefers the closed-loop flight's per-frame chain and judges it against 60 ms."""

from __future__ import annotations

import json

from hilrig import latency_budget
from kinect_emulator.renderer import KINECT_V1_EXPOSURE_TO_USB_MS


def _stage(median, p95):
    return {"median_ms": median, "p95_ms": p95}


def test_closed_loop_figures_are_printed_and_judged(tmp_path, capsys, monkeypatch):
    lat = {k: _stage(10.0, 20.0) for k, _ in latency_budget.CLOSED_LOOP_STAGES}
    lat.update(frames=42, capture_to_pwm=_stage(58.0, 90.0))
    (tmp_path / "slam_loop_scenario2.json").write_text(json.dumps({"latency_ms": lat}))
    monkeypatch.setattr("sys.argv", ["latency_budget.py", str(tmp_path)])
    assert latency_budget.main() == 0
    out = capsys.readouterr().out
    assert any(
        line.split()[-1] == "60.0"
        for line in out.splitlines()
        if "sum of the stage medians" in line
    )
    assert "58.0 /   90.0   over 42 frames (slam_loop_scenario2.json); target <= 60: met" in out
    k = KINECT_V1_EXPOSURE_TO_USB_MS
    modelled = [line for line in out.splitlines() if "exposure -> PWM, Kinect v1 modelled" in line]
    assert modelled and f"{58.0 + k:6.1f} / {90.0 + k:6.1f}" in modelled[0]
    lat["capture_to_pwm"] = _stage(61.0, 90.0)
    (tmp_path / "slam_loop_scenario2.json").write_text(json.dumps({"latency_ms": lat}))
    latency_budget.main()
    assert "target <= 60: MISSED" in capsys.readouterr().out


def test_without_a_closed_loop_flight_unmeasured_stages_are_named(tmp_path, capsys, monkeypatch):
    (tmp_path / "stream.json").write_text(json.dumps({"capture_to_receive_median_ms": 7.0}))
    monkeypatch.setattr("sys.argv", ["latency_budget.py", str(tmp_path)])
    latency_budget.main()
    out = capsys.readouterr().out
    assert "capture -> received" in out and "7.0" in out
    assert "missing: SLAM front end per frame, PID + command out (quad-control)" in out
