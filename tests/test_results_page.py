"""scripts/results.py and scripts/results_write.py: two result files give the expected Markdown,
the page is deterministic and idempotent, a measured kind replaces its carried-over record, and
make bench's metrics files become figures with verdicts.
"""

import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

import results  # noqa: E402
import results_write  # noqa: E402

BENCH = {
    "kind": "bench",
    "date": "2026-12-05",
    "commit": "abc1234",
    "machine": {"cores": 2, "cpu_model": "Test CPU"},
    "loadavg": [0.5, 0.25, 0.1],
    "figures": [
        {
            "name": "ATE orb localmap",
            "value": 0.0118,
            "unit": "m",
            "target": 0.01,
            "verdict": "MISS",
            "data": "fr1_xyz_first300",
            "mode": "wait",
        },
        {
            "name": "frames dropped",
            "value": 0,
            "unit": "frames",
            "target": 0,
            "verdict": "PASS",
            "data": "fr1_xyz_first300",
            "mode": "real time",
        },
    ],
}
HIL = {
    "kind": "hil",
    "date": "2026-12-04",
    "commit": None,
    "machine": {"cores": 2, "cpu_model": None},
    "loadavg": "idle",
    "figures": [
        {
            "name": "hold a|b",
            "value": "0.1 .. 0.2",
            "unit": "m",
            "verdict": None,
            "data": None,
            "mode": "HIL",
        },
    ],
}

EXPECTED_SECTIONS = """## SLAM engine on the TUM excerpts (`make bench`)

Measured: 2026-12-05, commit abc1234; 2 cores, Test CPU; load average 0.5 / 0.25 / 0.1.

| figure | value | unit | target | verdict | data | mode |
|---|---|---|---|---|---|---|
| ATE orb localmap | 0.0118 | m | 0.01 | MISS | fr1_xyz_first300 | wait |
| frames dropped | 0 | frames | 0 | PASS | fr1_xyz_first300 | real time |

## Hardware-in-loop scenarios (`make hil`)

Measured: 2026-12-04, commit not recorded; 2 cores, CPU model not recorded; load average idle.

| figure | value | unit | target | verdict | data | mode |
|---|---|---|---|---|---|---|
| hold a\\|b | 0.1 .. 0.2 | m | - | - | - | HIL |
"""


def write_inputs(tmp_path: Path) -> Path:
    d = tmp_path / "results"
    d.mkdir()
    # hil first on disk: the page orders kinds, not files
    (d / "hil.json").write_text(json.dumps(HIL))
    (d / "bench.json").write_text(json.dumps(BENCH))
    return d


def run_page(results_dir: Path, out: Path, seed: Path, *extra: str):
    return subprocess.run(
        [
            sys.executable,
            str(REPO / "scripts" / "results.py"),
            "--results-dir",
            str(results_dir),
            "--seed",
            str(seed),
            "--out",
            str(out),
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_two_result_files_give_the_expected_page(tmp_path):
    # GIVEN a bench and a hil result file, no seed
    d = write_inputs(tmp_path)
    out = tmp_path / "results.md"
    # WHEN the page is generated
    r = run_page(d, out, tmp_path / "no-seed.json")
    # THEN it is the header followed by both kinds in the fixed order, figures as recorded
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert text == results.HEADER + "\n" + EXPECTED_SECTIONS


def test_the_page_is_deterministic_and_idempotent(tmp_path):
    d = write_inputs(tmp_path)
    out = tmp_path / "results.md"
    run_page(d, out, tmp_path / "no-seed.json")
    first = out.read_bytes()
    # WHEN generated again THEN the bytes are the same and --check agrees
    run_page(d, out, tmp_path / "no-seed.json")
    assert out.read_bytes() == first
    assert run_page(d, out, tmp_path / "no-seed.json", "--check").returncode == 0
    # AND --check notices a hand edit
    out.write_text(first.decode() + "edited\n")
    assert run_page(d, out, tmp_path / "no-seed.json", "--check").returncode == 1


def test_a_measured_kind_replaces_its_carried_over_record(tmp_path):
    # GIVEN a seed with an old bench record and a study record, and a measured bench file
    old_bench = dict(BENCH, date="2026-11-01", figures=[])
    study = dict(BENCH, kind="study", figures=[])
    seed = tmp_path / "seed.json"
    seed.write_text(json.dumps([old_bench, study]))
    d = tmp_path / "results"
    d.mkdir()
    (d / "bench.json").write_text(json.dumps(BENCH))
    out = tmp_path / "results.md"
    # WHEN the page is generated
    assert run_page(d, out, seed).returncode == 0
    text = out.read_text()
    # THEN bench is the measured one and study is labelled carried over
    assert "Measured: 2026-12-05" in text and "2026-11-01" not in text
    assert "Carried over from the documentation: 2026-12-05" in text
    assert text.index("(`make bench`)") < text.index("(`make study`)")


def test_bench_metrics_become_figures_with_verdicts(tmp_path):
    # GIVEN make bench's layout: per-sequence runs and a real-time run
    out = tmp_path / "bench"
    for rel, metrics in {
        "fr1_xyz_first300/orb_localmap": {"ate_rmse_m": 0.0118},
        "fr1_xyz_first300/sift_glc": {"ate_rmse_m": 0.0120},
        "fr2_desk_first50/orb_localmap": {"ate_rmse_m": 0.0025},
        "realtime_orb_localmap": {"ate_rmse_m": 0.0117, "frontend_dropped": 0},
        "rate_2_cc_on": {"ate_rmse_m": 0.0114},
        "anchor/fr1_360_first60_wait_restart_on": {"ate_rmse_m": 0.09, "frames_lost": 2},
        "anchor/fr1_xyz_first300_realtime_restart_on": {"ate_rmse_m": 0.0104, "frames_lost": 0},
        "anchor/fr1_xyz_first300_realtime_restart_off": {"ate_rmse_m": 0.0117, "frames_lost": 0},
    }.items():
        (out / rel).mkdir(parents=True)
        (out / rel / "metrics.json").write_text(json.dumps(metrics))
    # WHEN the figures are extracted
    figs = {(f["name"], f["data"], f["mode"]): f for f in results_write.bench_figures(out)}
    # THEN the targets of the local map give verdicts, other systems none
    assert figs["ATE orb localmap", "fr1_xyz_first300", "wait"]["verdict"] == "MISS"
    assert figs["ATE orb localmap", "fr2_desk_first50", "wait"]["verdict"] is None
    assert figs["ATE sift glc", "fr1_xyz_first300", "wait"]["verdict"] is None
    # AND the anchor runs: frames lost against 0 and fr1_xyz in real time against ORB-SLAM2's
    # median, for the default (restart on) only
    assert figs["frames lost orb localmap, restart on", "fr1_360_first60", "wait"]["verdict"] == (
        "MISS"
    )
    rt = "real time"
    assert figs["ATE orb localmap, restart on", "fr1_xyz_first300", rt]["verdict"] == "PASS"
    assert figs["ATE orb localmap, restart off", "fr1_xyz_first300", rt]["verdict"] is None
    assert figs["frames dropped orb localmap", "fr1_xyz_first300", "real time"]["verdict"] == "PASS"
    assert figs["ATE orb localmap, every 2nd frame, cross-check on", "fr1_xyz_first300", "wait"]


def test_a_written_result_has_the_machine_and_checkout(tmp_path):
    path = results_write.write_result(
        "bench", [results_write.figure("x", 1.0, "m", target=2.0)], tmp_path
    )
    record = json.loads(path.read_text())
    assert record["kind"] == "bench" and record["figures"][0]["verdict"] == "PASS"
    assert record["machine"]["cores"] >= 1
    assert set(record) == {"kind", "date", "commit", "machine", "loadavg", "figures"}
