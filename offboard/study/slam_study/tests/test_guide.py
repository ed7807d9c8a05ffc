"""The frame-rate guide: cell lookup, 'not enough data', the lowest rate meeting a target."""

from __future__ import annotations

import numpy as np
import pytest

from slam_study import cli, guide, report
from slam_study.tests.test_tables import make_pairs


def _dense_pairs():
    # 6 pairs in each of: 8-10 mm x 0.4-0.6 deg (RPE 3 mm), 16-18 mm x 0.8-1.0 deg (RPE 9 mm);
    # 2 pairs in 4-6 mm x 0.2-0.4 deg (thin).
    trans = [9.0] * 6 + [17.0] * 6 + [5.0] * 2
    rot = [0.5] * 6 + [0.9] * 6 + [0.3] * 2
    rpe = [3.0] * 6 + [9.0] * 6 + [1.0] * 2
    return make_pairs(trans, rot, rpe_mm=rpe)


def test_prediction_uses_the_cell_of_the_per_frame_motion():
    # 0.27 m/s, 15 deg/s: 9 mm + 0.5 deg per frame at 30 fps, 18 mm + 1 deg at 15 fps
    preds = guide.predict(_dense_pairs(), 0.27, 15.0, fps_list=(30.0, 15.0, 16.0, 54.0, 2.0))
    at30, at15, at16, at54, at2 = preds
    assert at30.enough and at30.cell.trans_mean_mm == pytest.approx(3.0)
    assert at15.cell is None and not at15.enough  # 18 mm: above the 17 mm measured
    assert at2.cell is None  # 135 mm: beyond the 17 mm measured
    assert at16.enough and at16.cell.trans_mean_mm == pytest.approx(9.0)
    assert at54.cell.n == 2 and not at54.enough  # thin cell: not enough data


def test_lowest_rate_meeting_target():
    preds = guide.predict(_dense_pairs(), 0.27, 15.0, fps_list=(30.0, 16.0))
    assert guide.lowest_fps_meeting(preds, 10.0).fps == 16.0
    assert guide.lowest_fps_meeting(preds, 5.0).fps == 30.0
    assert guide.lowest_fps_meeting(preds, 1.0) is None
    text = guide.guide_text(preds, 0.27, 15.0, 1.0, "test")
    assert "No candidate rate is known to meet 1 mm" in text


@pytest.mark.parametrize("v, w", [(-0.1, 1.0), (float("nan"), 1.0), (0.1, float("inf"))])
def test_bad_velocities_are_rejected(v, w):
    with pytest.raises(ValueError):
        guide.predict(_dense_pairs(), v, w)


def test_guide_cli_reads_pairs_csv(tmp_path, capsys):
    p = _dense_pairs()
    report.write_pairs_csv(
        tmp_path / "pairs.csv", [report.Source("s", p, [("d", "orb", "vo", 1, p)])]
    )
    back, source, names = report.read_pairs_csv(tmp_path / "pairs.csv")
    assert source == "s" and names == ["s"] and len(back) == len(p)
    np.testing.assert_allclose(back.gt_trans_mm, p.gt_trans_mm)
    assert (
        cli.main(
            [
                "guide",
                "--trans-vel",
                "0.27",
                "--rot-vel",
                "15",
                "--target-rpe-mm",
                "5",
                "--report",
                str(tmp_path),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "Lowest frame rate meeting 5 mm per frame: 30.00 fps" in out
    assert "outside the measured motion: no prediction" in out  # 3.75 fps: 72 mm per frame
    assert "outside what was measured at 15.00, 10.00" in out
    assert (
        cli.main(
            ["guide", "--trans-vel", "0.27", "--rot-vel", "15", "--report", str(tmp_path / "none")]
        )
        == 2
    )
    with pytest.raises(SystemExit):
        cli.main(["guide", "--trans-vel", "-1", "--rot-vel", "15"])


def test_platform_table_reports_envelope_or_not_enough_data():
    table = guide.platform_table(_dense_pairs())
    assert table.rows[0][0] == "30"
    assert table.rows[0][3] == "not enough data"  # no pure-rotation pairs at all
    empty = guide.platform_table(make_pairs([], []))
    assert empty.rows[0][1] == "not enough data"


def test_default_source_is_the_densest_sweep_source():
    rows = [{"source": "a"}, {"source": "b"}, {"source": "b"}, {"source": "c"}, {"source": "c"}]
    assert report.default_source(rows) == "b"
    rows += [{"source": "slam-eval orb-vo"}]
    assert report.default_source(rows) == "slam-eval orb-vo"


def test_lowest_rate_stops_at_the_first_rate_missing_the_target():
    # 9 mm/frame cell (3 mm) at 30 fps, 17 mm cell (9 mm) at 16 fps; a noisy 3 mm cell lower down
    trans = [9.0] * 6 + [17.0] * 6 + [40.0] * 6
    rot = [0.5] * 6 + [0.9] * 6 + [2.0] * 6
    pairs = make_pairs(trans, rot, rpe_mm=[3.0] * 6 + [9.0] * 6 + [3.0] * 6)
    preds = guide.predict(pairs, 0.27, 15.0, fps_list=(30.0, 16.0, 6.75))
    assert preds[2].enough and preds[2].cell.trans_mean_mm == pytest.approx(3.0)
    assert guide.lowest_fps_meeting(preds, 5.0).fps == 30.0


def test_fast_turns_reduced_in_rate_have_cells():
    # GIVEN pairs of a fast turn with frames dropped: 30 mm + 12 deg per frame (fr1/360 at 10 fps)
    pairs = make_pairs(
        [30.0] * 6 + [9.0] * 6, [12.0] * 6 + [0.5] * 6, rpe_mm=[20.0] * 6 + [3.0] * 6
    )
    # WHEN the guide is asked about 0.3 m/s, 120 deg/s: 30 mm + 12 deg per frame at 10 fps
    at10, at5 = guide.predict(pairs, 0.3, 120.0, fps_list=(10.0, 5.0))
    # THEN that rate is answered from the 25-35 mm x 10-14 deg cell, and 24 deg at 5 fps, above
    # the 12 deg measured, is outside
    assert (
        at10.enough and at10.rot_bin == "10-14" and at10.cell.trans_mean_mm == pytest.approx(20.0)
    )
    assert at5.cell is None
