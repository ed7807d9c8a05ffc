"""TUM file reading and association: clear errors on bad input, the benchmark's 20 ms rule."""

from __future__ import annotations

import numpy as np
import pytest

from slam_study import tum


@pytest.mark.parametrize(
    "content, message",
    [
        ("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", ":2: expected 8 fields"),
        ("1.0 0 0 x 0 0 0 1\n", ":1: not a number"),
        ("1.0 0 0 nan 0 0 0 1\n", ":1: non-finite"),
        ("1.0 0 0 0 0 0 0 0\n", ":1: zero quaternion"),
        ("# only a comment\n", "no poses"),
    ],
)
def test_given_malformed_trajectory_then_error_names_file_and_line(tmp_path, content, message):
    path = tmp_path / "t.tum"
    path.write_text(content)
    with pytest.raises(tum.TumFormatError, match=message):
        tum.read_trajectory(path)


def test_given_missing_file_then_clear_error(tmp_path):
    with pytest.raises(tum.TumFormatError, match="cannot read"):
        tum.read_trajectory(tmp_path / "absent.txt")
    with pytest.raises(tum.TumFormatError, match="missing rgb.txt"):
        tum.Dataset.load(tmp_path)


def test_trajectory_round_trip_sorts_and_deduplicates(tmp_path):
    path = tmp_path / "t.tum"
    path.write_text("2.0 1 2 3 0 0 0 1\n1.0 0 0 0 0 0 0.7071068 0.7071068\n2.0 9 9 9 0 0 0 1\n")
    traj = tum.read_trajectory(path)
    assert list(traj.stamps_s) == [1.0, 2.0]
    np.testing.assert_allclose(traj.poses[1, :3, 3], [1, 2, 3])
    tum.write_trajectory(tmp_path / "u.tum", traj)
    again = tum.read_trajectory(tmp_path / "u.tum")
    np.testing.assert_allclose(again.poses, traj.poses, atol=1e-6)


@pytest.mark.parametrize(
    "a, b, expected",
    [
        ([1.000, 2.000], [1.019, 2.021], [(0, 0)]),  # 21 ms is outside the window
        ([1.000, 1.010], [1.008], [(1, 0)]),  # nearest wins, one-to-one
        ([1.0, 2.0, 3.0], [], []),
    ],
)
def test_association_rule(a, b, expected):
    ia, ib = tum.associate(np.array(a), np.array(b))
    assert list(zip(ia.tolist(), ib.tolist(), strict=False)) == expected


def test_dataset_reduction_keeps_every_kth_frame(fr1_xyz30):
    ds = tum.Dataset.load(fr1_xyz30)
    assert ds.rgb_stamps_s.size == 30
    assert len(ds.groundtruth_at_frames(1)) == 30
    reduced = ds.groundtruth_at_frames(3)
    np.testing.assert_array_equal(reduced.stamps_s, ds.rgb_stamps_s[::3])


def test_find_datasets_accepts_dataset_or_parent(fr1_xyz30, fr1_desk9, tmp_path):
    assert tum.find_datasets([fr1_xyz30]) == [fr1_xyz30]
    parent = fr1_xyz30.parent
    assert set(tum.find_datasets([parent])) == {fr1_xyz30, fr1_desk9}
    with pytest.raises(tum.TumFormatError, match="not a folder"):
        tum.find_datasets([tmp_path / "nope"])
