"""The fast-manoeuvre sequence's bookkeeping (hilrig.manoeuvres) without a flight: a manoeuvre
quad-control refuses ends the sequence as a scored miss, the craft is still landed and the report
is complete."""

from types import SimpleNamespace

import pytest
from hilrig import manoeuvres


class FakeFlight:
    """What fast_manoeuvres reads of a SlamFlight, with quad-control's state scripted."""

    def __init__(self, state: dict):
        self.state_now = state
        self.rig = SimpleNamespace(
            fc=SimpleNamespace(events=[(5e6, "failsafe after landing"), (1e6, "mode change")]),
            snapshot=lambda: None,
            realtime_factor=1.0,
        )
        self.options = SimpleNamespace(mount=None)

    def state(self) -> dict:
        return self.state_now


@pytest.fixture
def scripted(monkeypatch):
    """Take-off, hold and land recorded instead of flown; fly_manoeuvre refuses from the n-th."""
    calls = []

    def fly(flight, start, origin, goal, request, progress=None):
        calls.append(request)
        if len(calls) >= scripted.refuse_from:
            raise manoeuvres.ManoeuvreRefused("manoeuvre refused (409): only in hold")
        return {"request": request, "hold": {"max_m": 0.05}}

    def land(flight, progress=None):
        calls.append("land")
        return {"t_land_sim_s": 4.0, "handed_over_to_failsafe": False}

    monkeypatch.setattr(manoeuvres.missions, "take_off", lambda f, p=None: {"start_room_m": 0})
    monkeypatch.setattr(manoeuvres.missions, "hold", lambda f, s, t, p=None: {"max_m": 0.04})
    monkeypatch.setattr(manoeuvres.missions, "land", land)
    monkeypatch.setattr(manoeuvres, "fly_manoeuvre", fly)
    monkeypatch.setattr(manoeuvres, "camera_room_position", lambda s, m: (0.0, 0.0, 0.0))
    scripted.calls = calls
    scripted.refuse_from = 99
    return scripted


def _scores(report: dict) -> dict:
    return {**report, "ate": {"ate_rmse_m": 0.01}}


def test_a_refused_manoeuvre_ends_the_sequence_lands_and_is_a_named_miss(scripted):
    scripted.refuse_from = 4
    flight = FakeFlight({"state": "lost-hold", "last_event": "tracking lost, holding neutral"})
    report = manoeuvres.fast_manoeuvres(flight)
    assert len(scripted.calls) == 5 and scripted.calls[-1] == "land"
    assert len(report["manoeuvres"]) == 3 and report["manoeuvres_planned"] == 5
    assert report["refused"]["state"] == "lost-hold"
    assert report["failsafe_events"] == []  # the one after the landing began is not the flight's
    misses = manoeuvres.targets_missed(_scores(report), 0.03, 0.15)
    assert any("refused" in m and "lost-hold" in m for m in misses)
    assert "3 of 5 manoeuvres flown" in misses


def test_a_complete_sequence_within_limits_misses_nothing_and_a_wide_hold_is_named(scripted):
    report = manoeuvres.fast_manoeuvres(FakeFlight({"state": "hold", "manoeuvres_done": 5}))
    assert report["refused"] is None and len(report["manoeuvres"]) == 5
    assert manoeuvres.targets_missed(_scores(report), 0.03, 0.15) == []
    report["manoeuvres"][2]["hold"]["max_m"] = 0.2
    (miss,) = manoeuvres.targets_missed(_scores(report), 0.03, 0.15)
    assert "hold after" in miss and "0.2" in miss
