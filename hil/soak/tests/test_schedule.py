"""The soak's fault schedule (soak.schedule): reproducible from its seed, every kind often enough,
overlaps, nothing in the take-off's first seconds, one ground-station kill per mission at most and
after the mission's other faults have started. Pure Python, no flight."""

from __future__ import annotations

from collections import Counter

import pytest
from soak.schedule import (
    FAULT_KINDS,
    FAULT_RANGES,
    FAULT_WINDOW_END_S,
    TAKEOFF_QUIET_S,
    make_schedule,
    overlapping_pairs,
)

SEEDS = (1, 2, 20261206, 987654321)


def test_same_seed_gives_the_same_schedule():
    # GIVEN one seed and length WHEN the schedule is made twice THEN both are equal, fault by fault
    assert make_schedule(42, 60).to_dict() == make_schedule(42, 60).to_dict()


def test_different_seeds_give_different_schedules():
    a, b = make_schedule(1, 60), make_schedule(2, 60)
    assert [f.kind for f in a.faults()] != [f.kind for f in b.faults()]
    assert [f.at_s for f in a.faults()] != [f.at_s for f in b.faults()]


@pytest.mark.parametrize("seed", SEEDS)
def test_every_kind_at_least_ten_times_in_sixty_minutes(seed):
    counts = Counter(f.kind for f in make_schedule(seed, 60).faults(within_minutes=60))
    assert set(counts) == set(FAULT_KINDS)
    assert min(counts.values()) >= 10, counts


@pytest.mark.parametrize("seed", SEEDS)
def test_faults_overlap(seed):
    faults = make_schedule(seed, 60).faults(within_minutes=60)
    pairs = overlapping_pairs(faults)
    # Overlaps of different kinds, in many missions: not one lucky pair.
    assert len({a.mission for a, b in pairs if a.kind != b.kind}) >= 10


@pytest.mark.parametrize("seed", SEEDS)
def test_no_fault_in_the_take_off_and_all_start_in_the_window(seed):
    for f in make_schedule(seed, 60).faults():
        assert TAKEOFF_QUIET_S <= f.at_s <= FAULT_WINDOW_END_S, f


@pytest.mark.parametrize("seed", SEEDS)
def test_one_ground_station_kill_per_mission_after_the_other_faults_started(seed):
    for m in make_schedule(seed, 60).missions:
        kills = [f for f in m.faults if f.kind == "ground_station_kill"]
        assert len(kills) <= 1, m
        if kills:
            assert all(f.at_s <= kills[0].at_s for f in m.faults), m


@pytest.mark.parametrize("seed", SEEDS)
def test_parameters_within_their_ranges(seed):
    for f in make_schedule(seed, 60).faults():
        ranges = FAULT_RANGES[f.kind]
        lo, hi = ranges["duration_s"]
        assert lo <= f.duration_s <= hi, f
        assert set(f.params) == set(ranges) - {"duration_s"}, f
        for name, value in f.params.items():
            lo, hi = ranges[name]
            assert lo <= value <= hi, (f, name)


def test_stream_stalls_span_the_stated_range():
    stalls = [f.duration_s for f in make_schedule(7, 600).faults() if f.kind == "stream_stall"]
    assert min(stalls) < 0.5 and max(stalls) > 2.5


def test_longer_soak_has_more_missions():
    assert len(make_schedule(5, 120).missions) > len(make_schedule(5, 60).missions)


@pytest.mark.parametrize("minutes", [0, -1, float("nan"), float("inf")])
def test_bad_length_is_refused(minutes):
    with pytest.raises(ValueError, match="minutes"):
        make_schedule(1, minutes)
