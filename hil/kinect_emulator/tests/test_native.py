"""The C++ renderer (libkinect_render.so via native.py) against the numpy reference.

Tolerance: none - depth and RGB must be IDENTICAL, pixel for pixel. The C++ code repeats numpy's
float32 operations in numpy's order (built with -ffp-contract=off: no fused multiply-add) and takes
the random draws from the same numpy generator, so no rounding differs; even silhouette edges (where
one ulp in a ray parameter could flip a pixel between the crate and the wall behind it) match, and
the test keeps them in. A difference means the two back ends have drifted apart.

When the build tree (RGBD_BUILD_DIR or build/) is configured with hil/ on, the library must be
there: its absence fails (it was supposed to be built by `make build`); only without a configured
build tree are the comparisons skipped, with the reason.
"""

import numpy as np
import pytest
from kinect_emulator import (
    Box,
    Intrinsics,
    KinectEmulator,
    KinectOptions,
    Room,
    camera_pose_from_ned,
    default_room,
    load_textures,
    native,
    pose_matrix,
)


@pytest.fixture(scope="module")
def built():
    if native.library_path().is_file():
        return True
    if native.expected_built():
        pytest.fail(
            f"{native.library_path()} is missing but {native.build_dir()} is configured to build "
            "it (hil/kinect_emulator/CMakeLists.txt): run `make build`"
        )
    pytest.skip(f"no configured build tree at {native.build_dir()} (run `make build`)")


@pytest.fixture(scope="module")
def room():
    return default_room()


def _look_at(eye, target) -> np.ndarray:
    """T_room_cam of a camera at eye looking at target, image rows going down (room -z)."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return pose_matrix(np.column_stack([x, y, z]), eye)


# Poses that exercise every branch: the flight circle of bench.py, the crate and the pillar with
# their silhouettes and projector shadows, a corner of the room, straight down, straight up (rays
# parallel to two axes: +-inf ray parameters), a box corner behind the camera (whole-image
# obstacle test), the near range limit.
POSES = {
    "flight_1": camera_pose_from_ned(
        [0.3, 0.2, -1.7], 0.02, -0.03, 0.4, 30.0, origin_room_m=(-0.5, 1.5, 0.2)
    ),  # fmt: skip
    "flight_2": camera_pose_from_ned(
        [1.2, 1.1, -1.2], -0.05, 0.08, 2.1, 30.0, origin_room_m=(-0.5, 1.5, 0.2)
    ),  # fmt: skip
    "crate": _look_at([0.5, -0.5, 1.4], [2.1, -1.8, 0.5]),
    "pillar": _look_at([0.0, 0.5, 1.2], [-2.4, 1.8, 1.2]),
    "corner": _look_at([2.0, 1.0, 2.0], [4.0, 3.0, 3.0]),
    "down": pose_matrix(np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 2.5]),
    "up": pose_matrix(np.eye(3), [0.0, 0.0, 0.5]),
    "pillar_behind": _look_at([-2.0, 1.5, 1.5], [-3.5, 2.5, 1.0]),  # its top corners are behind
    "beside_crate": _look_at([1.4, -1.0, 0.9], [4.0, -2.5, 0.2]),
    "near_wall": _look_at([3.7, 0.0, 1.5], [4.0, 0.0, 1.5]),
}


def test_the_pillar_pose_tests_the_pillar_over_the_whole_image(room):
    emu = KinectEmulator(room, KinectOptions(renderer="numpy"))
    T = POSES["pillar_behind"]
    assert emu._screen_rect(room.obstacles[1], T[:3, :3], T[:3, 3]) == (0, 480, 0, 640)


def _pair(room, **opts):
    a = KinectEmulator(room, KinectOptions(renderer="numpy", **opts))
    b = KinectEmulator(room, KinectOptions(renderer="cpp", **opts))
    assert (a.renderer, b.renderer) == ("numpy", "cpp")
    return a, b


def _assert_same(fa, fb, what):
    d_depth = fa.depth_mm.astype(np.int32) - fb.depth_mm.astype(np.int32)
    d_rgb = fa.rgb.astype(np.int16) - fb.rgb.astype(np.int16)
    assert not d_depth.any(), (
        f"{what}: depth differs at {np.count_nonzero(d_depth)} px (max {np.abs(d_depth).max()} mm)"
    )
    n_rgb = np.count_nonzero(d_rgb.any(axis=2))
    assert not d_rgb.any(), f"{what}: RGB differs at {n_rgb} px (max {np.abs(d_rgb).max()})"


@pytest.mark.parametrize("name", sorted(POSES))
def test_given_a_pose_when_both_back_ends_render_then_the_images_are_identical(built, room, name):
    a, b = _pair(room, seed=7)
    T = POSES[name]
    for index in (0, 5):  # two noise draws per pose
        fa = a.render_indexed(T, 1000, index)
        fb = b.render_indexed(T, 1000, index)
        assert fb.rgb.shape == (480, 640, 3) and fb.depth_mm.dtype == np.uint16
        assert np.count_nonzero(fb.depth_mm) > 0 or name == "near_wall"
        _assert_same(fa, fb, f"{name} #{index}")


@pytest.mark.parametrize(
    "opts",
    [
        dict(
            depth_noise=False,
            quantise=False,
            shadows=False,
            dropout_fraction=0.0,
            rgb_noise_std=0.0,
        ),  # fmt: skip
        dict(shadows=False),
        dict(quantise=False, dropout_fraction=0.2, rgb_noise_std=9.0),
        dict(min_range_m=1.0, max_range_m=3.0),
    ],
)
def test_given_sensor_options_when_both_back_ends_render_then_identical(built, room, opts):
    a, b = _pair(room, seed=3, **opts)
    for name in ("crate", "flight_2"):
        _assert_same(a.render(POSES[name], 0), b.render(POSES[name], 0), f"{name} {opts}")


def test_given_a_sequence_then_the_random_streams_stay_in_step(built, room):
    """Sequential render() draws the same numbers in the same order on both back ends."""
    a, b = _pair(room, seed=11, blank_frames=frozenset({2}))
    for i in range(5):
        fa, fb = a.render(POSES["flight_1"], i * 33333), b.render(POSES["flight_1"], i * 33333)
        assert fa.blank == fb.blank
        _assert_same(fa, fb, f"frame {i}")


def test_given_a_small_room_and_camera_then_identical(built):
    """Other intrinsics, texture size and obstacles than the defaults (nothing is hard-wired)."""
    tex = load_textures(max_count=3)[:, :200, :300]
    small = Room(
        bounds=Box((-2.0, -1.5, 0.0), (2.0, 1.5, 2.5)),
        textures=np.ascontiguousarray(tex),
        obstacles=[
            Box((0.5, -0.5, 0.0), (1.0, 0.5, 0.8)),
            Box((-1.5, 0.8, 0.0), (-1.2, 1.1, 2.5)),
            Box((-0.2, -1.5, 1.0), (0.2, -1.2, 1.3)),
        ],  # fmt: skip
        tile_w_m=0.7,
        tile_h_m=0.5,
    )
    intr = Intrinsics(width=160, height=120, fx=130.0, fy=131.0, cx=79.2, cy=61.7)
    a, b = _pair(small, intrinsics=intr, seed=5)
    T = _look_at([-1.0, 0.0, 1.2], [1.0, 0.0, 0.4])
    _assert_same(a.render(T, 0), b.render(T, 0), "small room")


def test_given_a_pose_outside_the_room_then_the_cpp_back_end_refuses_it_too(built, room):
    _, b = _pair(room)
    with pytest.raises(ValueError):
        b.render(pose_matrix(np.eye(3), [9.0, 0.0, 1.0]), 0)
    with pytest.raises(ValueError):
        b.render(np.full((4, 4), np.nan), 0)


def test_given_auto_then_cpp_is_chosen_when_built(built, room):
    assert KinectEmulator(room, KinectOptions(renderer="auto")).renderer == "cpp"


def test_given_a_missing_library_then_auto_falls_back_and_cpp_raises(room, monkeypatch, tmp_path):
    monkeypatch.setenv("RGBD_BUILD_DIR", str(tmp_path))
    monkeypatch.setattr(native, "_lib", None)
    assert KinectEmulator(room, KinectOptions(renderer="auto")).renderer == "numpy"
    with pytest.raises(OSError):
        KinectEmulator(room, KinectOptions(renderer="cpp"))
    with pytest.raises(ValueError):
        KinectOptions(renderer="gl").validate()
