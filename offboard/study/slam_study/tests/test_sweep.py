"""The sweep with a stand-in slam-eval: outputs, resumability, failures, the report."""

from __future__ import annotations

import json

import pytest

from slam_study import cli, sweep


def _run_cli(out, data, slam_eval, *extra):
    return cli.main(
        [
            "run",
            "--data",
            str(data),
            "--out",
            str(out),
            "--slam-eval",
            str(slam_eval),
            "--features",
            "sift,orb",
            "--backends",
            "vo",
            "--k",
            "1,2",
            "--jobs",
            "2",
            *extra,
        ]
    )


def test_sweep_runs_every_job_resumes_and_reports(tmp_path, fr1_xyz30, fake_slam_eval, monkeypatch):
    log = tmp_path / "invocations.txt"
    monkeypatch.setenv("FAKE_SLAM_EVAL_LOG", str(log))
    monkeypatch.setenv("FAKE_SLAM_EVAL_FAIL", "orb")
    out = tmp_path / "report"
    # WHEN the sweep runs: 2 detectors x 1 back-end x 2 rates
    assert _run_cli(out, fr1_xyz30, fake_slam_eval) == 0
    assert len(log.read_text().splitlines()) == 4
    ok = json.loads((out / "runs/fr1_xyz_first30/sift-vo-k2/result.json").read_text())
    bad = json.loads((out / "runs/fr1_xyz_first30/orb-vo-k1/result.json").read_text())
    assert ok["status"] == "ok" and bad["status"] == "failed"
    assert ok["cpu_s"] > 0.0  # the stand-in's own CPU time, from wait4
    assert "exited with 3" in bad["reason"]
    assert "configured to fail" in (out / "runs/fr1_xyz_first30/orb-vo-k1/stderr.txt").read_text()
    report = (out / "report.md").read_text()
    record = json.loads((out / "sweep.json").read_text())["invocations"][-1]
    assert record["runs_ok"] == 2 and record["runs_failed"] == 2
    assert "Table 4.14" in report and "Table 4.20a" in report and "Table 3.4" in report
    assert (
        "| fr1_xyz_first30 | orb-vo | 1 | slam-eval exited with 3: fake-slam-eval: orb is "
        "configured to fail |"
    ) in report
    assert (out / "plots" / "traj_fr1_xyz_first30.png").stat().st_size > 1000
    assert (out / "tables" / "table_4_5_rpe.csv").is_file()
    pairs_lines = (out / "pairs.csv").read_text().splitlines()
    assert len(pairs_lines) == 1 + 29 + 14  # sift at k=1 and k=2
    # WHEN it runs again THEN nothing is redone; with --retry-failed only the failures are
    assert _run_cli(out, fr1_xyz30, fake_slam_eval) == 0
    assert len(log.read_text().splitlines()) == 4
    monkeypatch.delenv("FAKE_SLAM_EVAL_FAIL")
    assert _run_cli(out, fr1_xyz30, fake_slam_eval, "--retry-failed", "--no-report") == 0
    assert len(log.read_text().splitlines()) == 6
    history = json.loads((out / "sweep.json").read_text())["invocations"]
    assert [h["runs_this_invocation"] for h in history] == [4, 0, 2]
    assert (
        json.loads((out / "runs/fr1_xyz_first30/orb-vo-k1/result.json").read_text())["status"]
        == "ok"
    )


def test_run_rejects_missing_binary_and_data(tmp_path, fr1_xyz30, capsys):
    assert _run_cli(tmp_path / "r", fr1_xyz30, tmp_path / "no-slam-eval") == 2
    assert "slam-eval not found" in capsys.readouterr().err
    assert (
        cli.main(
            [
                "run",
                "--data",
                str(tmp_path),
                "--out",
                str(tmp_path / "r"),
                "--slam-eval",
                "/bin/true",
            ]
        )
        == 2
    )
    assert "no TUM-layout dataset" in capsys.readouterr().err


def test_job_list_and_names(fr1_xyz30, fr1_desk9):
    jobs = sweep.make_jobs(
        [fr1_xyz30, fr1_desk9], ["sift", "surf", "orb"], ["vo", "llc", "glc"], [1, 2, 3]
    )
    assert len(jobs) == 2 * 9 * 3
    assert jobs[0].name == "fr1_xyz_first30/sift-vo-k1"


def test_progress_line_counts_failures():
    import io

    stream = io.StringIO()
    ticks = iter([0.0, 1.5, 3.0])
    progress = sweep.Progress(2, stream, lambda: next(ticks), width=10)
    progress.update("a", True)
    progress.update("b", False)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("[#####.....] 1/2 runs (0 failed)    1.5 s  a")
    assert lines[1].endswith("b FAILED") and "(1 failed)" in lines[1]


def test_a_source_without_pairs_still_renders(tmp_path):
    from slam_study import pairs, report

    (tmp_path / "tables").mkdir()
    (tmp_path / "plots").mkdir()
    md = "\n".join(report.pair_sections(report.Source("empty", pairs.empty_pairs(), []), tmp_path))
    assert "not enough data" in md and "Table 4.20a" in md
    assert (tmp_path / "plots" / "empty_grid.png").is_file()


def _rendered_copy(src, dst):
    """A TUM folder as hil/tools/render_tum.py writes it: its lists start with the renderer's
    line (the frames themselves are not read by the stand-in slam-eval)."""
    dst.mkdir()
    (dst / "rgb.txt").write_text(
        "# rendered by hil/tools/render_tum.py --out x --manoeuvre turn\n"
        + (src / "rgb.txt").read_text()
    )
    (dst / "groundtruth.txt").write_text((src / "groundtruth.txt").read_text())
    return dst


def test_rendered_folders_are_swept_apart_with_no_undistort_and_kept_out_of_the_table(
    tmp_path, fr1_desk9, fake_slam_eval, monkeypatch, capsys
):
    from slam_study import shipped, tum

    mixed = tmp_path / "mixed"
    mixed.mkdir()
    rendered = _rendered_copy(fr1_desk9, mixed / "hil_turn")
    (mixed / "fr1_desk_9frames").symlink_to(fr1_desk9)
    assert tum.is_rendered(rendered) and not tum.is_rendered(fr1_desk9)
    log = tmp_path / "invocations.txt"
    monkeypatch.setenv("FAKE_SLAM_EVAL_LOG", str(log))
    no_undistort = ("--slam-eval-args", "--no-map --quiet --no-undistort")
    # WHEN a rendered folder is swept without --no-undistort, or with a recording, or a recording
    # with --no-undistort THEN the sweep refuses before any run, naming the fix
    for data, extra, says in (
        (rendered, (), "add --no-undistort"),
        (mixed, no_undistort, "sweep them apart"),
        (fr1_desk9, no_undistort, "must be undistorted"),
    ):
        assert _run_cli(tmp_path / "r", data, fake_slam_eval, *extra) == 2
        assert says in capsys.readouterr().err
    assert not log.exists()
    # WHEN it is swept on its own with --no-undistort THEN every run gets the option
    out = tmp_path / "rendered-report"
    assert _run_cli(out, rendered, fake_slam_eval, "--no-report", *no_undistort) == 0
    lines = log.read_text().splitlines()
    assert len(lines) == 4 and all(line.endswith(" --no-undistort") for line in lines)
    # AND the guide's shipped table refuses its pairs (the guide predicts a camera's error)
    with pytest.raises(tum.TumFormatError, match="recorded sequences only"):
        shipped.write(out, tmp_path / "table.csv", lambda msg: None)
    assert not (tmp_path / "table.csv").exists()
