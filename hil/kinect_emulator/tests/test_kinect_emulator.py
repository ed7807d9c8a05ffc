"""Kinect emulator: exact geometry, the depth error model, fault injection, writers.

Deterministic: every emulator is seeded; geometry tests switch the noise off.
"""

import math

import numpy as np
import pytest
from kinect_emulator import (
    Box,
    FakenectDumpWriter,
    Intrinsics,
    KinectEmulator,
    KinectOptions,
    Room,
    TumFolderWriter,
    camera_pose_from_ned,
    default_room,
    load_textures,
    pose_matrix,
)
from kinect_emulator.poses import rotation_to_quaternion_xyzw
from kinect_emulator.renderer import BASELINE_M, DISPARITY_SUBPIXELS, IR_FOCAL_PX, NOISE_COEFF_PER_M
from kinect_emulator.writers import depth_mm_to_freenect_raw, freenect_raw_to_depth_mm
from PIL import Image

EXACT = dict(
    depth_noise=False, quantise=False, shadows=False, dropout_fraction=0.0, rgb_noise_std=0.0
)


@pytest.fixture(scope="module")
def textures():
    return load_textures(max_count=8)


@pytest.fixture(scope="module")
def room(textures):
    return default_room(textures)


def level_camera_at(x, y, z, yaw_rad=0.0, mount_pitch_down_deg=0.0):
    """T_room_cam for a level craft whose camera centre is at room (x, y, z) (no body offset)."""
    return camera_pose_from_ned(
        [x, -y, -z], 0.0, 0.0, yaw_rad, mount_pitch_down_deg, cam_offset_body_m=(0.0, 0.0, 0.0)
    )


def test_camera_pose_axes():
    T = level_camera_at(0.0, 0.0, 1.0)
    R = T[:3, :3]
    assert np.allclose(R[:, 2], [1, 0, 0])  # optical axis = room +x (north)
    assert np.allclose(R[:, 0], [0, -1, 0])  # image right = east = room -y
    assert np.allclose(R[:, 1], [0, 0, -1])  # image down = room -z
    Td = level_camera_at(0.0, 0.0, 1.0, mount_pitch_down_deg=90.0)
    assert np.allclose(Td[:3, 2], [0, 0, -1])  # looking straight down


def test_quaternion_round_trip():
    T = camera_pose_from_ned([0.3, 0.2, -1.5], 0.1, -0.2, 2.5, 30.0)
    x, y, z, w = rotation_to_quaternion_xyzw(T[:3, :3])
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    assert np.allclose(R, T[:3, :3], atol=1e-9)


@pytest.mark.parametrize("x0", [-1.0, 0.0, 1.3])
def test_depth_facing_wall_equals_distance(room, x0):
    # GIVEN a camera facing the +x wall (x = 4 m) square on THEN every wall pixel reads 4 - x0
    emu = KinectEmulator(room, KinectOptions(**EXACT))
    z, _, face = emu.raycast(level_camera_at(x0, 0.5, 2.5))
    z = z.reshape(480, 640)
    face = face.reshape(480, 640)
    assert face[255, 318] == 1  # principal point sees face "x max"
    wall = face == 1
    assert wall.mean() > 0.5
    assert np.allclose(z[wall], 4.0 - x0, atol=1e-5)


def test_depth_at_principal_point_analytic_tilted(room):
    # GIVEN a camera 1.5 m up pitched 30 deg down THEN the principal ray meets the floor at
    # distance h / sin(30) and its camera depth is that distance (the ray is the optical axis).
    i = Intrinsics(cx=320.0, cy=240.0)
    emu = KinectEmulator(room, KinectOptions(intrinsics=i, **EXACT))
    frame = emu.render(level_camera_at(-2.0, 0.0, 1.5, mount_pitch_down_deg=30.0), 0)
    assert frame.depth_mm[240, 320] == round(1.5 / math.sin(math.radians(30.0)) * 1000)


def test_floor_seen_from_above_is_flat(room):
    emu = KinectEmulator(room, KinectOptions(**EXACT))
    z, pts, face = emu.raycast(level_camera_at(-1.0, -0.5, 1.2, mount_pitch_down_deg=90.0))
    assert np.all(face == 4)  # z min = floor
    assert np.allclose(z, 1.2, atol=1e-5)
    assert np.allclose(pts[2], 0.0, atol=1e-5)


def test_obstacle_occludes_wall(room):
    # The crate spans x 1.5..2.7, y -2.2..-1.4, z 0..0.75: looking north from x=0 at y=-1.8, z=0.4
    emu = KinectEmulator(room, KinectOptions(**EXACT))
    z, _, face = emu.raycast(level_camera_at(0.0, -1.8, 0.4))
    z = z.reshape(480, 640)
    face = face.reshape(480, 640)
    assert face[255, 318] == 6 + 0  # obstacle 0, entered through its x-min face
    assert z[255, 318] == pytest.approx(1.5, abs=1e-5)


def test_camera_outside_free_space_is_a_clear_error(room):
    emu = KinectEmulator(room, KinectOptions(**EXACT))
    with pytest.raises(ValueError, match="outside"):
        emu.raycast(level_camera_at(5.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="outside"):
        emu.raycast(level_camera_at(2.0, -1.8, 0.5))  # inside the crate
    with pytest.raises(ValueError, match="4x4"):
        emu.raycast(np.full((4, 4), np.nan))


@pytest.mark.parametrize("z_m", [1.0, 2.0, 3.0])
def test_depth_noise_is_quadratic(room, z_m):
    emu = KinectEmulator(
        room,
        KinectOptions(
            depth_noise=True, quantise=False, shadows=False, dropout_fraction=0.0, seed=5
        ),
    )
    zt = np.full((480, 640), z_m, dtype=np.float32)
    err = emu.sensor_depth(zt) - zt
    assert np.nanstd(err) == pytest.approx(NOISE_COEFF_PER_M * z_m**2, rel=0.05)
    assert abs(np.nanmean(err)) < 0.1 * NOISE_COEFF_PER_M * z_m**2


def test_quantisation_follows_disparity_steps(room):
    emu = KinectEmulator(
        room, KinectOptions(depth_noise=False, quantise=True, shadows=False, dropout_fraction=0.0)
    )
    zt = np.linspace(0.6, 4.0, 640 * 480, dtype=np.float32).reshape(480, 640)
    zq = emu.sensor_depth(zt)
    k = IR_FOCAL_PX * BASELINE_M * DISPARITY_SUBPIXELS
    step = zt**2 / k
    assert np.all(np.abs(zq - zt) <= 0.5 * step * 1.01 + 1e-6)
    assert len(np.unique(zq[zt > 3.5])) < len(np.unique(zq[zt < 1.0]))  # coarser far away
    assert np.max(np.abs(zq - zt)[zt > 3.9]) > 0.015  # ~2 cm steps at 4 m


def test_range_limits_give_no_reading(room):
    emu = KinectEmulator(room, KinectOptions(**EXACT))
    zt = np.array([[0.3, 0.49, 0.51, 4.4, 4.6, np.inf]], dtype=np.float32)
    out = emu.sensor_depth(zt)
    assert np.isnan(out[0, [0, 1, 4, 5]]).all() and np.isfinite(out[0, [2, 3]]).all()


def test_dropout_fraction(room):
    emu = KinectEmulator(
        room,
        KinectOptions(
            depth_noise=False, quantise=False, shadows=False, dropout_fraction=0.02, seed=9
        ),
    )
    out = emu.sensor_depth(np.full((480, 640), 2.0, dtype=np.float32))
    assert np.isnan(out).mean() == pytest.approx(0.02, rel=0.1)


def test_projector_shadow_beside_occluding_edge(textures):
    # GIVEN a tall narrow box 1 m in front of a wall 3 m away THEN a hole of width f b (1/1 - 1/3)
    # px opens on the box's left (the projector sits to the camera's right)
    room = Room(
        Box((-1.0, -3.0, 0.0), (3.0, 3.0, 3.0)),
        textures,
        obstacles=[Box((1.0, -0.1, 0.0), (1.2, 0.1, 3.0))],
    )
    i = Intrinsics(cx=320.0, cy=240.0, fx=500.0, fy=500.0)
    opts = KinectOptions(
        intrinsics=i,
        depth_noise=False,
        quantise=False,
        shadows=True,
        dropout_fraction=0.0,
        rgb_noise_std=0.0,
    )
    frame = KinectEmulator(room, opts).render(level_camera_at(0.0, 0.0, 1.5), 0)
    row = frame.depth_mm[240]
    box_cols = np.where(row == 1000)[0]
    assert box_cols.size > 50
    left = box_cols.min()
    holes = np.where(row[:left] == 0)[0]
    expected_px = 500.0 * BASELINE_M * (1 / 1.0 - 1 / 3.0)  # 25 px
    assert holes.size == pytest.approx(expected_px, abs=2)
    assert holes.max() == left - 1  # adjacent to the edge
    assert np.all(row[box_cols.max() + 1 :] > 0)  # no shadow on the right side


def test_blank_frames_latency_and_schedule(room):
    emu = KinectEmulator(
        room, KinectOptions(fps=30.0, latency_ms=40.0, blank_frames=frozenset({1}))
    )
    T = level_camera_at(0.0, 0.0, 1.5, mount_pitch_down_deg=30.0)
    f0, f1, f2 = (emu.render(T, t) for t in (0, 33333, 66667))
    assert not f0.blank and f1.blank and not f2.blank
    assert f1.depth_mm.max() == 0 and f1.rgb.max() == 0
    assert f0.depth_mm.max() > 0 and f0.rgb.std() > 20
    assert f2.available_us - f2.capture_us == 40000
    assert emu.frames_due(0, 100000) == [33333, 66666, 99999]


def test_seeded_and_deterministic(room):
    T = level_camera_at(0.5, 0.5, 1.7, mount_pitch_down_deg=30.0)
    a = KinectEmulator(room, KinectOptions(seed=3)).render(T, 0)
    b = KinectEmulator(room, KinectOptions(seed=3)).render(T, 0)
    c = KinectEmulator(room, KinectOptions(seed=4)).render(T, 0)
    assert np.array_equal(a.depth_mm, b.depth_mm) and np.array_equal(a.rgb, b.rgb)
    assert not np.array_equal(a.depth_mm, c.depth_mm)


def _harris_corners(rgb: np.ndarray) -> int:
    """Number of strong Harris corners (numpy only): the texture SLAM's feature detectors need."""
    g = rgb.astype(np.float32).mean(axis=2)
    gx = np.zeros_like(g)
    gy = np.zeros_like(g)
    gx[:, 1:-1] = g[:, 2:] - g[:, :-2]
    gy[1:-1, :] = g[2:, :] - g[:-2, :]

    def box(a, r=2):
        c = np.cumsum(np.cumsum(np.pad(a, ((r + 1, r), (r + 1, r))), 0), 1)
        return (
            c[2 * r + 1 :, 2 * r + 1 :]
            - c[: -2 * r - 1, 2 * r + 1 :]
            - c[2 * r + 1 :, : -2 * r - 1]
            + c[: -2 * r - 1, : -2 * r - 1]
        )

    sxx, syy, sxy = box(gx * gx), box(gy * gy), box(gx * gy)
    resp = sxx * syy - sxy * sxy - 0.04 * (sxx + syy) ** 2
    strong = resp > 0.01 * resp.max()
    # count local maxima in 8x8 cells
    cells = strong[: 480 // 8 * 8, : 640 // 8 * 8].reshape(60, 8, 80, 8).any(axis=(1, 3))
    return int(cells.sum())


def test_rendered_views_are_textured_like_real_frames(room):
    # The real TUM frame and the emulated view should both have plenty of corners; a flat grey
    # room would have none.
    emu = KinectEmulator(room, KinectOptions(seed=2))
    f = emu.render(level_camera_at(-1.0, 0.0, 1.7, mount_pitch_down_deg=30.0), 0)
    n_emulated = _harris_corners(f.rgb)
    n_real = _harris_corners(room.textures[0])
    assert n_emulated > 0.3 * n_real and n_emulated > 300
    assert _harris_corners(np.full_like(f.rgb, 128)) == 0


def test_tum_writer_round_trip(room, tmp_path):
    emu = KinectEmulator(room, KinectOptions(seed=1))
    T = camera_pose_from_ned([0.2, 0.1, -1.7], 0.05, -0.03, 0.4, 30.0)
    frames = [emu.render(T, t) for t in (0, 33333)]
    with TumFolderWriter(tmp_path / "seq", t0_s=100.0) as w:
        stamps = [w.write(f) for f in frames]
    assert stamps == ["100.000000", "100.033333"]
    rgb_lines = [
        ln.split()
        for ln in (tmp_path / "seq/rgb.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    assert rgb_lines[1] == ["100.033333", "rgb/100.033333.png"]
    d = np.asarray(Image.open(tmp_path / "seq/depth/100.000000.png"))
    assert d.dtype == np.uint16 and d.shape == (480, 640)
    assert np.array_equal(d.astype(np.uint32), frames[0].depth_mm.astype(np.uint32) * 5)
    rgb = np.asarray(Image.open(tmp_path / "seq/rgb/100.033333.png"))
    assert np.array_equal(rgb, frames[1].rgb)
    gt = [
        ln.split()
        for ln in (tmp_path / "seq/groundtruth.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    assert len(gt) == 2
    assert np.allclose([float(v) for v in gt[0][1:4]], T[:3, 3], atol=1e-6)


def test_fakenect_dump(room, tmp_path):
    emu = KinectEmulator(room, KinectOptions(seed=1))
    f = emu.render(level_camera_at(0.0, 0.0, 1.7, mount_pitch_down_deg=30.0), 500000)
    with FakenectDumpWriter(tmp_path / "dump") as w:
        w.write(f)
    index = (tmp_path / "dump/INDEX.txt").read_text().split()
    assert index[0].startswith("d-0.500000-") and index[1].startswith("r-0.500000-")
    data = (tmp_path / "dump" / index[0]).read_bytes()
    header = b"P5 640 480 65535\n"
    assert data.startswith(header) and len(data) == len(header) + 640 * 480 * 2
    raw = np.frombuffer(data[len(header) :], dtype="=u2").reshape(480, 640)  # host order (fakenect)
    back = freenect_raw_to_depth_mm(raw)
    valid = f.depth_mm > 0
    assert np.all((raw == 2047) == ~valid)
    # 11-bit raw disparity is coarser than mm: within one disparity step (z^2 / 348 m) plus
    # rounding.
    z = f.depth_mm[valid] / 1000.0
    assert np.all(np.abs(back[valid].astype(float) - f.depth_mm[valid]) <= 1000 * z * z / 300 + 2)


def test_freenect_raw_conversion_limits():
    raw = depth_mm_to_freenect_raw(np.array([0, 500, 1000, 4000, 60000], dtype=np.uint16))
    assert raw[0] == 2047 and raw[-1] == 2047
    assert np.all(np.diff(raw[1:4].astype(int)) > 0)


@pytest.mark.parametrize(
    "bad", [dict(fps=0), dict(latency_ms=-1), dict(min_range_m=5.0), dict(dropout_fraction=1.0)]
)
def test_options_validation(room, bad):
    with pytest.raises(ValueError):
        KinectEmulator(room, KinectOptions(**bad))


def test_room_validation(textures):
    with pytest.raises(ValueError):
        Box((0, 0, 0), (1, -1, 1))
    with pytest.raises(ValueError, match="inside"):
        Room(Box((0, 0, 0), (1, 1, 1)), textures, obstacles=[Box((0.5, 0.5, 0), (2, 2, 1))])
    with pytest.raises(ValueError):
        Room(Box((0, 0, 0), (1, 1, 1)), np.zeros((2, 4, 4), np.uint8))
    with pytest.raises(FileNotFoundError):
        load_textures(["/nonexistent-dir"])


def test_pose_matrix_shape():
    assert pose_matrix(np.eye(3), [1, 2, 3])[2, 3] == 3
