"""hil/tools/render_tum.py: a rendered manoeuvre is a TUM folder slam-eval can read."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

TOOL = Path(__file__).resolve().parents[1] / "render_tum.py"
sys.path.insert(0, str(TOOL.parent))
import render_tum  # noqa: E402


def test_the_ramped_profile_reaches_the_total_without_a_step_in_rate():
    # GIVEN a 90 deg turn at 60 deg/s with a 0.5 s ramp, sampled at 30 fps
    s = render_tum.ramped_profile(math.radians(90), math.radians(60), 0.5, 1 / 30)
    # THEN it starts at 0, ends at the total, never goes back, and no step exceeds the peak rate
    assert s[0] == 0 and s[-1] == pytest.approx(math.radians(90))
    steps = np.diff(s)
    assert np.all(steps >= -1e-12)
    assert steps.max() <= math.radians(60) / 30 + 1e-9
    assert steps[0] < steps.max() / 2  # ramped, not stepped


def test_a_short_turn_is_written_as_a_tum_folder(tmp_path):
    # GIVEN a 20 deg turn at 120 deg/s (a handful of frames)
    out = tmp_path / "turn"
    r = subprocess.run(
        [
            sys.executable,
            str(TOOL),
            "--out",
            str(out),
            "--manoeuvre",
            "turn",
            "--turn-deg",
            "20",
            "--yaw-rate-deg-s",
            "120",
            "--ramp-s",
            "0.1",
            "--settle-s",
            "0",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 0, r.stderr

    # THEN rgb, depth and ground truth list the same stamps, and the images are what TUM stores
    def stamps(name):
        lines = (out / name).read_text().splitlines()
        return [ln.split()[0] for ln in lines if not ln.startswith("#")]

    rgb, depth, gt = stamps("rgb.txt"), stamps("depth.txt"), stamps("groundtruth.txt")
    assert len(rgb) >= 5 and rgb == depth == gt
    first = rgb[0]
    assert np.asarray(Image.open(out / "rgb" / f"{first}.png")).shape == (480, 640, 3)
    d = np.asarray(Image.open(out / "depth" / f"{first}.png"))
    assert d.dtype == np.uint16 and d.max() > 5000 * 0.5  # TUM scale, readings beyond 0.5 m
    # AND the ground truth turns by the asked angle about the room's vertical
    rows = [
        ln.split()
        for ln in (out / "groundtruth.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    q0, q1 = np.array(rows[0][4:8], float), np.array(rows[-1][4:8], float)
    angle = 2 * math.degrees(math.acos(min(1.0, abs(float(np.dot(q0, q1))))))
    assert angle == pytest.approx(20, abs=0.5)


def test_bad_options_and_a_used_folder_are_refused(tmp_path):
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "x").write_text("x")
    for args in (
        ["--out", str(tmp_path / "a"), "--yaw-rate-deg-s", "0"],
        ["--out", str(tmp_path / "used")],
    ):
        r = subprocess.run([sys.executable, str(TOOL), *args], capture_output=True, text=True)
        assert r.returncode == 2 and "render_tum:" in r.stderr
