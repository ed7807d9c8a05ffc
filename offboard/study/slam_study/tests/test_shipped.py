"""The guide's shipped table (data/guide_pairs.csv): up to date, stale tables caught, made from a
sweep, read by `slam-study guide` on a fresh clone (no sweep, no ../shared)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from slam_study import cli, guide, shipped, sweep, tum
from slam_study.tests.conftest import kRepo, kTestData


def _excerpts() -> dict[str, Path]:
    return {name: kRepo / rel for name, rel in shipped.kRepoExcerpts.items()}


def test_shipped_table_is_not_stale():
    """The staleness test, part 1 (what the repository can check by itself): fails when the rows
    were edited, the study code that makes them changed, or their ground-truth motion disagrees
    with the real TUM excerpts in tests/data. Fix: regenerate (message below)."""
    table = shipped.read()
    problems, checked = shipped.check(table, _excerpts(), include_engine=False)
    assert not problems, (
        "guide table stale:\n  " + "\n  ".join(problems) + "\n" + shipped.regenerate_hint()
    )
    recomputed = [c for c in checked if "recomputed" in c]
    assert len(recomputed) == 2 and all(" 0 rows" not in c for c in recomputed), checked


def test_guide_says_when_the_engine_changed_since_the_table_was_measured(tmp_path, capsys):
    """The staleness test, part 2: the engine's sources (offboard/slam, offboard/surf, slam-eval's
    main) change more often than the table can be re-measured (11 min on data outside the repo), so
    an engine change is not a test failure; instead every answer of the guide says that the table
    was measured with other engine sources and how to re-measure (`slam-study table --check`
    exits 1 on it)."""
    from slam_study import cli

    table = shipped.read()
    stale = _rewrite(table, table.rows, tmp_path / "stale.csv", engine_sources_sha256="0" * 64)
    assert shipped.engine_problem(shipped.read(stale)) is not None
    assert cli.main(["guide", "--trans-vel", "0.25", "--rot-vel", "10", "--table", str(stale)]) == 0
    assert "engine's sources changed" in capsys.readouterr().out
    fresh = _rewrite(table, table.rows, tmp_path / "fresh.csv")
    assert cli.main(["guide", "--trans-vel", "0.25", "--rot-vel", "10", "--table", str(fresh)]) == 0
    assert "engine's sources changed" not in capsys.readouterr().out


def _rewrite(table: shipped.ShippedTable, rows: list[dict], path: Path, **meta) -> Path:
    """A table file with `rows`, keeping the meta but with rows_sha256 recomputed and the engine
    hash of this tree (so that only the fault a test plants shows, whatever the engine's state)."""
    m = {
        **table.meta,
        "rows_sha256": shipped.rows_sha256(rows),
        "engine_sources_sha256": shipped.engine_sources_sha256(),
        **meta,
    }
    path.write_text("".join(f"# {k}: {v}\n" for k, v in m.items()) + shipped._rows_text(rows))
    return path


@pytest.fixture
def table() -> shipped.ShippedTable:
    return shipped.read()


def test_check_catches_a_row_edited_by_hand(table, tmp_path):
    path = _rewrite(table, table.rows, tmp_path / "t.csv")
    assert shipped.check(shipped.read(path), _excerpts())[0] == []
    text = path.read_text()
    row = next(line for line in text.splitlines() if line.startswith("orb-vo,"))
    edited = row.rsplit(",", 2)[0] + ",1.000," + row.rsplit(",", 1)[1]  # rpe_trans_mm := 1 mm
    path.write_text(text.replace(row, edited, 1))
    problems, _ = shipped.check(shipped.read(path), _excerpts())
    assert len(problems) == 1 and "rows_sha256" in problems[0]


def test_check_recomputes_ground_truth_motion_from_tests_data(table, tmp_path):
    # GIVEN a table whose hash is consistent but one fr1/xyz row's motion is off by 0.01 mm
    rows = [dict(r) for r in table.rows]
    first30 = tum.Dataset.load(kTestData / "fr1_xyz_first30")
    i = next(
        i
        for i, r in enumerate(rows)
        if r["dataset"] == "fr1_xyz_first300"
        and first30.rgb_stamps_s[0] <= float(r["stamp_s"])
        and float(r["stamp_s"]) + float(r["dt_s"]) < first30.rgb_stamps_s[-1]
    )
    rows[i]["gt_trans_mm"] = f"{float(rows[i]['gt_trans_mm']) + 0.01:.3f}"
    problems, _ = shipped.check(
        shipped.read(_rewrite(table, rows, tmp_path / "t.csv")), _excerpts()
    )
    # THEN only the recomputation from the real excerpt finds it
    assert len(problems) == 1 and "recomputed from fr1_xyz_first30" in problems[0]


def test_check_catches_changed_engine_and_study_code(table, tmp_path):
    # GIVEN a copy of the engine's sources with one line changed
    root = tmp_path / "repo"
    for entry in shipped.kEngineSources:
        src = kRepo / entry
        if src.is_dir():
            shutil.copytree(src, root / entry)
        else:
            (root / entry).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(src, root / entry)
    assert shipped.engine_sources_sha256(root) == shipped.engine_sources_sha256(kRepo)
    # a test or document does not change a trajectory, a source file does
    (root / "offboard/slam/tests/extra_test.cpp").write_text("// a new test\n")
    assert shipped.engine_sources_sha256(root) == shipped.engine_sources_sha256(kRepo)
    src = next((root / "offboard/slam").rglob("*.cpp"))
    src.write_text(src.read_text() + "\n// changed\n")
    problems, _ = shipped.check(table, _excerpts(), root=root)
    assert any("engine's sources changed" in p for p in problems)
    # and a table made by other study code
    path = _rewrite(table, table.rows, tmp_path / "t.csv", study_code_sha256="0" * 64)
    problems, _ = shipped.check(shipped.read(path), _excerpts())
    assert len(problems) == 1 and "study code" in problems[0]


def test_cli_check_exit_status(tmp_path, capsys, table):
    path = _rewrite(table, table.rows, tmp_path / "t.csv")
    assert cli.main(["table", "--check", "--out", str(path)]) == 0
    path = _rewrite(table, table.rows[:-1], tmp_path / "t.csv", rows_sha256="bad")
    assert cli.main(["table", "--check", "--out", str(path)]) == 1
    assert "is stale: regenerate" in capsys.readouterr().err


def test_table_from_a_sweep_then_guide(
    tmp_path, fr1_xyz30, fr1_desk9, fake_slam_eval, monkeypatch, capsys
):
    # GIVEN a sweep (stand-in slam-eval) on the two real excerpts, with the tree's engine hash
    monkeypatch.setattr(cli, "_engine_sha256", lambda _: shipped.engine_sources_sha256())
    out = tmp_path / "study"
    data = tmp_path / "data"
    data.mkdir()
    for d in (fr1_xyz30, fr1_desk9):
        (data / d.name).symlink_to(d)
    assert (
        cli.main(
            [
                "run",
                "--data",
                str(data),
                "--out",
                str(out),
                "--slam-eval",
                str(fake_slam_eval),
                "--features",
                "sift,orb",
                "--backends",
                "vo,glc",
                "--k",
                "1,2",
                "--jobs",
                "2",
                "--no-report",
            ]
        )
        == 0
    )
    # WHEN the table is written
    path = tmp_path / "guide_pairs.csv"
    assert cli.main(["table", "--report", str(out), "--out", str(path)]) == 0
    t = shipped.read(path)
    # THEN it holds the vo runs only, both datasets, and passes the check on the same excerpts
    assert t.sources() == ["orb-vo", "sift-vo"] and list(t.datasets) == [
        "fr1_desk_9frames",
        "fr1_xyz_first30",
    ]
    assert len(t.rows) == 2 * ((29 + 14) + (8 + 4))
    problems, checked = shipped.check(
        t, {"fr1_xyz_first30": fr1_xyz30, "fr1_desk_9frames": fr1_desk9}
    )
    assert not problems and "same ground-truth file" in " ".join(checked)
    # AND the guide reads it, naming the data per cell
    assert cli.main(["guide", "--trans-vel", "0.2", "--rot-vel", "10", "--table", str(path)]) == 0
    text = capsys.readouterr().out
    assert "Data: slam-eval orb-vo, 55 frame pairs" in text  # most pairs; a tie goes by name
    assert "fr1_desk_9frames, fr1_xyz_first30 (TUM RGB-D excerpts)" in text
    # WHEN the engine changes THEN the sweep redoes the runs, and old runs are refused
    job = sweep.make_jobs([fr1_desk9], ["orb"], ["vo"], [1], engine_sources_sha256="new")[0]
    assert not sweep.is_finished(job, out, retry_failed=False)
    monkeypatch.setattr(shipped, "engine_sources_sha256", lambda root=None: "new")
    with pytest.raises(tum.TumFormatError, match="rerun the sweep"):
        shipped.write(out, tmp_path / "again.csv", lambda _: None)


def test_guide_on_a_fresh_clone_states_data_interval_and_range(capsys):
    # slow, thesis-typical (fr1/desk, thesis Table 3.3), beyond anything measured
    assert cli.main(["guide", "--trans-vel", "0.1", "--rot-vel", "3"]) == 0
    slow = capsys.readouterr().out
    assert "Data: slam-eval " in slow and "fr1_xyz_first300" in slow and "95 % CI" in slow
    assert (
        cli.main(["guide", "--trans-vel", "0.41", "--rot-vel", "23", "--target-rpe-mm", "10"]) == 0
    )
    typical = capsys.readouterr().out
    assert "Lowest frame rate meeting 10 mm" in typical or "No candidate rate" in typical
    # 5 m/s, 400 deg/s: 167 mm and 13 deg per frame even at 30 fps, above the 100-140 mm cell that
    # holds the largest measured translation (fr1/xyz at 3.75 fps)
    assert cli.main(["guide", "--trans-vel", "5", "--rot-vel", "400"]) == 0
    beyond = capsys.readouterr().out
    assert "outside what was measured at every candidate rate" in beyond


def test_guide_help_shows_an_example(capsys):
    with pytest.raises(SystemExit):
        cli.main(["guide", "--help"])
    assert (
        "slam-study guide --trans-vel 0.41 --rot-vel 23 --target-rpe-mm 8"
        in capsys.readouterr().out
    )


def test_flight_summary_from_a_trajectory(tmp_path):
    # GIVEN a camera moving 0.1 m/s along x for 5 s, sampled at 30 Hz
    stamps = np.arange(0, 5, 1 / 30)
    poses = np.stack([np.eye(4)] * stamps.size)
    poses[:, 0, 3] = 0.1 * stamps
    gt = tmp_path / "groundtruth.tum"
    tum.write_trajectory(gt, tum.Trajectory(stamps, poses))
    text = guide.flight_summary(gt, 15.0, 8.0)
    assert "the camera moved 0.10 m/s, 0.0 deg/s" in text and "at the 15 fps flown" in text
    assert "--trans-vel 0.10 --rot-vel 0.0 --target-rpe-mm 8" in text
