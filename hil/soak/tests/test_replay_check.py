"""Which lock schedule the soak's replay check holds a mission's replay to."""

from __future__ import annotations

from soak.replay_check import LOCK_SCHEDULE_FILE, lock_schedule_of


def _map(tmp_path, name: str, with_schedule: bool = True):
    d = tmp_path / name
    d.mkdir(parents=True)
    if with_schedule:
        (d / LOCK_SCHEDULE_FILE).write_text("L t 1\n")
    return str(d)


def test_a_mission_flown_on_one_map_replays_in_lock_step_with_its_schedule(tmp_path):
    one = _map(tmp_path, "slam-tables/map-2")
    assert (
        lock_schedule_of({"slam_maps": [one]})
        == tmp_path / "slam-tables/map-2" / LOCK_SCHEDULE_FILE
    )


def test_a_restarted_slam_server_or_a_missing_schedule_means_wait_mode(tmp_path):
    # Several maps: the later ones resumed from a checkpoint no single record covers.
    maps = [_map(tmp_path, "slam-tables/map-3"), _map(tmp_path, "slam-tables-1/map-1")]
    assert lock_schedule_of({"slam_maps": maps}) is None
    # One map without a schedule (a slam-server from before it recorded one), or none noted.
    assert (
        lock_schedule_of({"slam_maps": [_map(tmp_path, "old/map-1", with_schedule=False)]}) is None
    )
    assert lock_schedule_of({}) is None
