"""Binning into the thesis's tables: thresholds, bins, single-axis selection, velocities."""

from __future__ import annotations

import numpy as np
import pytest

from slam_study import tables, tum, velocity
from slam_study.pairs import PairTable


def make_pairs(trans_mm, rot_deg, rpe_mm=None, rpe_deg=None, trans_share=None, rot_share=None):
    n = len(trans_mm)
    return PairTable(
        stamp_s=np.arange(n, dtype=float),
        dt_s=np.full(n, 1 / 30),
        gt_trans_mm=np.asarray(trans_mm, float),
        gt_rot_deg=np.asarray(rot_deg, float),
        trans_share=np.asarray(trans_share if trans_share is not None else [[1 / 3] * 3] * n),
        rot_share=np.asarray(rot_share if rot_share is not None else [[1 / 3] * 3] * n),
        rpe_trans_mm=np.asarray(rpe_mm if rpe_mm is not None else np.ones(n), float),
        rpe_rot_deg=np.asarray(rpe_deg if rpe_deg is not None else np.full(n, 0.1), float),
    )


def _row(table, label):
    return next(r for r in table.rows if r[0] == label)


def test_translation_study_selects_low_rotation_and_bins_half_open():
    # GIVEN pairs at bin edges, and one with too much rotation for the translation study
    p = make_pairs(
        trans_mm=[1.0, 1.99, 2.0, 5.0, 5.0],
        rot_deg=[0.1, 0.1, 0.29, 0.1, 0.3],
        rpe_mm=[1.0, 3.0, 7.0, 2.0, 100.0],
    )
    t414, _ = tables.translation_study(p)
    assert _row(t414, "1-2")[1:3] == ["2 (thin)", "2.00 ± 1.00"]
    assert _row(t414, "2-4")[1] == "1 (thin)"
    assert _row(t414, "4-6")[2] == "2.00 ± 0.00"  # the 0.3 deg pair is excluded
    assert _row(t414, "15-19")[1] == "0"


def test_single_axis_translation_needs_more_than_80_percent():
    shares = [[0.81, 0.1, 0.09], [0.80, 0.1, 0.1], [0.0, 0.05, 0.95]]
    p = make_pairs([5.0, 5.0, 5.0], [0.1, 0.1, 0.1], rpe_mm=[2.0, 9.0, 4.0], trans_share=shares)
    _, t415 = tables.translation_study(p)
    row = _row(t415, "4-6")
    assert row[1].startswith("2.00 ± 0.00 [1")  # x: only the 0.81 pair
    assert row[2].startswith("- [0")
    assert row[3].startswith("4.00 ± 0.00 [1")  # z


def test_rotation_study_selects_low_translation_and_single_axis_at_85_percent():
    shares = [[0.9, 0.05, 0.05], [0.84, 0.16, 0.0], [0.0, 0.0, 1.0]]
    p = make_pairs([1.0, 2.9, 3.0], [0.5, 0.5, 0.5], rpe_deg=[0.2, 0.4, 9.0], rot_share=shares)
    t417, t418 = tables.rotation_study(p)
    assert _row(t417, "0.4-0.6")[1] == "2 (thin)"  # the 3 mm pair is excluded
    assert _row(t417, "0.4-0.6")[3] == "0.300 ± 0.100"
    row = _row(t418, "0.4-0.6")
    assert row[1].startswith("0.200 ± 0.000 [1")  # roll: 0.9 share
    assert row[3].startswith("- [0")  # yaw pair is the excluded 3 mm one


def test_joint_grid_is_9x9_and_places_pairs():
    p = make_pairs([17.0, 17.5, 1.5, 18.0], [1.7, 1.79, 0.15, 1.7], rpe_mm=[30, 40, 1, 99])
    t_tab, r_tab, cells = tables.joint_grid(p)
    assert len(cells) == 9 and all(len(row) == 9 for row in cells)
    assert cells[8][8].n == 2 and cells[8][8].trans_mean_mm == pytest.approx(35.0)
    assert cells[0][0].n == 1
    assert sum(c.n for row in cells for c in row) == 3  # 18.0 mm is outside [16, 18)
    assert t_tab.rows[8][9] == "35.00 ± 5.00 [2]"
    assert len(r_tab.rows) == 9


def test_velocity_tables_convert_bins_to_speeds():
    p = make_pairs([1.5], [0.05])
    t416, t419 = tables.velocity_tables(p)
    assert _row(t416, "1-2")[1:4] == ["0.030-0.060", "0.020-0.040", "0.010-0.020"]
    assert _row(t419, "0.1-0.2")[1:4] == ["3.0-6.0", "2.0-4.0", "1.0-2.0"]


def test_markdown_and_csv_render_every_row():
    t414, _ = tables.translation_study(make_pairs([1.5], [0.1]))
    md = t414.markdown()
    assert md.count("\n|") == 2 + len(tables.kTransStudyEdgesMm) - 1
    assert t414.csv().splitlines()[0].startswith("translation mm/frame,n,")


def test_rate_stats_on_real_excerpt(fr1_xyz30):
    """Reducing the frame rate keeps the velocity but multiplies the motion per frame."""
    ds = tum.Dataset.load(fr1_xyz30)
    s1 = velocity.rate_stats(ds, 1)
    s3 = velocity.rate_stats(ds, 3)
    assert s1.frames == 30 and s3.frames == 10
    assert s1.fps == pytest.approx(30.0, rel=0.05)
    assert s3.fps == pytest.approx(10.0, rel=0.05)
    assert s3.trans_mm_per_frame == pytest.approx(3 * s1.trans_mm_per_frame, rel=0.25)
    assert s3.trans_m_per_s == pytest.approx(s1.trans_m_per_s, rel=0.1)
    assert s1.window_s == pytest.approx(0.97, abs=0.02)  # the excerpt is shorter than 1 s
    assert velocity.rate_stats(ds, 30) is None
    with pytest.raises(ValueError):
        velocity.rate_stats(ds, 0)
    table = velocity.rate_table(ds, [1, 3, 30])
    assert [r[0] for r in table.rows] == ["1", "3", "30"]


def test_velocity_definition_reproduces_thesis_table_3_3(fr1_desk9):
    """GIVEN fr1/desk's full ground truth (shipped in tests/data) WHEN its velocity is computed
    over the whole recording THEN it matches thesis Table 3.3 (23.4 s, 0.413 m/s, 23.3 deg/s)."""
    from slam_study import thesis

    gt = tum.read_trajectory(fr1_desk9 / "groundtruth.txt")
    v_m_s, w_deg_s, window = velocity.windowed_velocity(gt, gt.stamps_s[0], gt.stamps_s[-1])
    published = thesis.kTable33["freiburg1_desk"]
    assert window == pytest.approx(1.0)
    assert gt.stamps_s[-1] - gt.stamps_s[0] == pytest.approx(published["duration_s"], abs=0.05)
    assert v_m_s == pytest.approx(published["trans_m_per_s"], abs=0.0015)
    assert w_deg_s == pytest.approx(published["rot_deg_per_s"], abs=0.06)
