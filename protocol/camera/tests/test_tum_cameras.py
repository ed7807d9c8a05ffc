"""The TUM camera contract: generated files fresh, and the models sane (positive focal lengths, a
principal point inside the 640x480 image, five distortion coefficients)."""

import pathlib
import subprocess
import sys

import pytest
from rgbd_protocol import tum_cameras

HERE = pathlib.Path(__file__).resolve().parent


def test_generated_files_are_up_to_date():
    gen = HERE.parent / "tools" / "gen_tum_cameras.py"
    proc = subprocess.run(
        [sys.executable, str(gen), "--check"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.parametrize("cam", tum_cameras.TUM_CAMERAS.values(), ids=lambda c: c.name)
def test_models_are_plausible_kinect_colour_cameras(cam):
    assert 400 < cam.fx_px < 700 and 400 < cam.fy_px < 700
    assert 0 < cam.cx_px < 640 and 0 < cam.cy_px < 480
    assert len(cam.distortion) == 5
    assert cam.intrinsics()["distortion"] == list(cam.distortion)


def test_lookup_by_name_and_depth_scale():
    assert tum_cameras.TUM_CAMERAS["fr1"] is tum_cameras.TUM_FR1
    assert tum_cameras.TUM_DEPTH_UNITS_PER_M > 0
