"""TUM RGB-D file formats: trajectories (`t tx ty tz qx qy qz qw`), frame lists (`t filename`),
dataset folders, and nearest-timestamp association.

A dataset folder is any folder in the benchmark's layout: `rgb.txt` (required), `groundtruth.txt`
(required by the study; it classifies every pair by its ground-truth motion), `depth.txt`, `rgb/`,
`depth/`. Errors name the file and line; nothing here reads the clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slam_study import se3

# The benchmark's own association rule: rgb, depth and ground truth match when their stamps differ
# by at most 20 ms (TUM associate.py default; data/README.md).
kMaxAssociationDiffS = 0.02


class TumFormatError(ValueError):
    """A TUM file or folder that cannot be used: the message names the path (and line)."""


@dataclass(frozen=True)
class Trajectory:
    """Timestamped poses T_world_cam. stamps_s: (N,) seconds, increasing; poses: (N,4,4)."""

    stamps_s: np.ndarray
    poses: np.ndarray

    def __len__(self) -> int:
        return int(self.stamps_s.shape[0])

    def positions_m(self) -> np.ndarray:
        return self.poses[:, :3, 3]

    def subset(self, indices: np.ndarray) -> Trajectory:
        idx = np.asarray(indices, dtype=int)
        return Trajectory(self.stamps_s[idx], self.poses[idx])


def _data_lines(path: Path):
    try:
        text = path.read_text()
    except OSError as err:
        raise TumFormatError(f"{path}: cannot read ({err.strerror})") from err
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].replace(",", " ").strip()
        if line:
            yield lineno, line.split()


def read_trajectory(path: str | Path) -> Trajectory:
    """Reads a TUM trajectory; sorts by time, drops exact duplicate stamps (keeps the first)."""
    path = Path(path)
    rows = []
    for lineno, fields in _data_lines(path):
        if len(fields) != 8:
            raise TumFormatError(
                f"{path}:{lineno}: expected 8 fields 't tx ty tz qx qy qz qw', got {len(fields)}"
            )
        try:
            values = [float(f) for f in fields]
        except ValueError as err:
            raise TumFormatError(f"{path}:{lineno}: not a number ({err})") from err
        if not all(np.isfinite(values)):
            raise TumFormatError(f"{path}:{lineno}: non-finite value")
        if np.linalg.norm(values[4:8]) < 1e-6:
            raise TumFormatError(f"{path}:{lineno}: zero quaternion")
        rows.append(values)
    if not rows:
        raise TumFormatError(f"{path}: no poses")
    data = np.array(rows)
    data = data[np.argsort(data[:, 0], kind="stable")]
    keep = np.concatenate([[True], np.diff(data[:, 0]) > 0])
    data = data[keep]
    return Trajectory(data[:, 0], se3.make_poses(data[:, 1:4], data[:, 4:8]))


def write_trajectory(path: str | Path, traj: Trajectory) -> None:
    lines = []
    for stamp, pose in zip(traj.stamps_s, traj.poses, strict=False):
        q = se3.rot_to_quat_xyzw(pose[:3, :3])
        t = pose[:3, 3]
        lines.append(
            f"{stamp:.6f} {t[0]:.6f} {t[1]:.6f} {t[2]:.6f} "
            f"{q[0]:.6f} {q[1]:.6f} {q[2]:.6f} {q[3]:.6f}"
        )
    Path(path).write_text("\n".join(lines) + "\n")


def read_frame_list(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """Reads `rgb.txt`/`depth.txt`: (stamps_s sorted, filenames)."""
    path = Path(path)
    stamps, names = [], []
    for lineno, fields in _data_lines(path):
        if len(fields) < 2:
            raise TumFormatError(f"{path}:{lineno}: expected 'timestamp filename'")
        try:
            stamp = float(fields[0])
        except ValueError as err:
            raise TumFormatError(f"{path}:{lineno}: bad timestamp ({err})") from err
        if not np.isfinite(stamp):
            raise TumFormatError(f"{path}:{lineno}: non-finite timestamp")
        stamps.append(stamp)
        names.append(fields[1])
    if not stamps:
        raise TumFormatError(f"{path}: no frames")
    order = np.argsort(stamps, kind="stable")
    return np.asarray(stamps)[order], [names[i] for i in order]


def associate(
    stamps_a: np.ndarray, stamps_b: np.ndarray, max_diff_s: float = kMaxAssociationDiffS
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-timestamp matching, one-to-one, |ta - tb| <= max_diff_s (TUM associate.py rule:
    candidate pairs taken greedily in order of increasing difference). Returns index arrays
    (ia, ib) sorted by ia."""
    a = np.asarray(stamps_a, dtype=float)
    b = np.asarray(stamps_b, dtype=float)
    if a.size == 0 or b.size == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    order_b = np.argsort(b)
    sorted_b = b[order_b]
    candidates = []
    # Every b within the window of each a (windows are narrow: a few neighbours at most).
    lo = np.searchsorted(sorted_b, a - max_diff_s, side="left")
    hi = np.searchsorted(sorted_b, a + max_diff_s, side="right")
    for ia in range(a.size):
        for pos in range(lo[ia], hi[ia]):
            candidates.append((abs(a[ia] - sorted_b[pos]), ia, int(order_b[pos])))
    candidates.sort()
    used_a, used_b, pairs = set(), set(), []
    for _, ia, ib in candidates:
        if ia not in used_a and ib not in used_b:
            used_a.add(ia)
            used_b.add(ib)
            pairs.append((ia, ib))
    pairs.sort()
    if not pairs:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    arr = np.array(pairs, dtype=int)
    return arr[:, 0], arr[:, 1]


@dataclass(frozen=True)
class Dataset:
    """A TUM-layout folder: colour frame stamps and the ground-truth trajectory."""

    name: str
    path: Path
    rgb_stamps_s: np.ndarray
    groundtruth: Trajectory

    @staticmethod
    def load(path: str | Path) -> Dataset:
        path = Path(path)
        if not path.is_dir():
            raise TumFormatError(f"{path}: not a folder")
        for required in ("rgb.txt", "groundtruth.txt"):
            if not (path / required).is_file():
                raise TumFormatError(f"{path}: missing {required} (not a TUM-layout dataset)")
        stamps, _ = read_frame_list(path / "rgb.txt")
        return Dataset(path.name, path.resolve(), stamps, read_trajectory(path / "groundtruth.txt"))

    def groundtruth_at_frames(self, k: int = 1) -> Trajectory:
        """Ground truth at every k-th colour frame (nearest within 20 ms; unmatched frames dropped),
        stamped with the frame's time."""
        stamps = self.rgb_stamps_s[::k]
        ia, ib = associate(stamps, self.groundtruth.stamps_s)
        return Trajectory(stamps[ia], self.groundtruth.poses[ib])


# hil/tools/render_tum.py starts rgb.txt (and its other lists) with this line: the frames are the
# HIL Kinect emulator's, not a camera's (no lens distortion, no motion blur, no rolling shutter).
kRenderedHeader = "# rendered by hil/tools/render_tum.py"


def is_rendered(path: str | Path) -> bool:
    """True for a dataset folder written by hil/tools/render_tum.py (rgb.txt's first line)."""
    try:
        with (Path(path) / "rgb.txt").open() as fh:
            return fh.readline().startswith(kRenderedHeader)
    except OSError:
        return False


def is_dataset(path: str | Path) -> bool:
    p = Path(path)
    return (p / "rgb.txt").is_file() and (p / "groundtruth.txt").is_file()


def find_datasets(roots: list[str | Path]) -> list[Path]:
    """Each root that is a dataset, else its immediate sub-folders that are (sorted by name)."""
    found = []
    for root in roots:
        r = Path(root)
        if not r.is_dir():
            raise TumFormatError(f"{r}: not a folder")
        if is_dataset(r):
            found.append(r)
        else:
            found.extend(sorted(p for p in r.iterdir() if p.is_dir() and is_dataset(p)))
    return found
