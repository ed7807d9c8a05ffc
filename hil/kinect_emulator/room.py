"""The room the emulated Kinect sees: an axis-aligned box plus axis-aligned obstacle boxes.

World frame of the room: x, y horizontal, z up, metres; the floor is z = 0. Each surface is tiled
with
real photographs: tile (i, j) of a face shows texture number hash(face, i, j) mod N, so neighbouring
tiles differ and feature matchers meet real, non-repeating texture over a few metres.
Textures are RGB uint8 arrays of equal size, loaded once (`load_textures`). Immutable after build.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]
# Real TUM RGB-D frames shipped in the repository (CC BY 4.0, credit in tests/data/README.md).
DEFAULT_TEXTURE_DIRS = (
    REPO_ROOT / "tests/data/fr1_xyz_first30/rgb",
    REPO_ROOT / "tests/data/fr1_desk_9frames/rgb",
)


@dataclass(frozen=True)
class Box:
    """Axis-aligned box, min/max corners in room coordinates (m)."""

    lo_m: tuple[float, float, float]
    hi_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not all(a < b for a, b in zip(self.lo_m, self.hi_m, strict=False)):
            raise ValueError(
                f"Box corners must satisfy lo < hi on every axis: {self.lo_m} {self.hi_m}"
            )


@dataclass
class Room:
    """Interior of `bounds` is free space; `obstacles` are solid boxes inside it."""

    bounds: Box
    textures: np.ndarray  # (N, H, W, 3) uint8
    obstacles: list[Box] = field(default_factory=list)
    # One texture tile covers this many metres: 1.2 m x 0.9 m keeps the photographs' 4:3 aspect and
    # (with the 60 % window each tile shows) roughly the real scale of the TUM office scenes.
    tile_w_m: float = 1.2
    tile_h_m: float = 0.9

    def __post_init__(self) -> None:
        t = self.textures
        if t.ndim != 4 or t.shape[3] != 3 or t.dtype != np.uint8 or t.shape[0] < 1:
            raise ValueError("Room.textures must be a non-empty (N, H, W, 3) uint8 array")
        if not (self.tile_w_m > 0 and self.tile_h_m > 0):
            raise ValueError("Room tile sizes must be > 0")
        for o in self.obstacles:
            if not all(
                bl <= ol and oh <= bh
                for bl, ol, oh, bh in zip(
                    self.bounds.lo_m, o.lo_m, o.hi_m, self.bounds.hi_m, strict=False
                )
            ):
                raise ValueError(f"obstacle {o} is not inside the room bounds")

    def contains(self, p_m) -> bool:
        """True when p is in free space (inside the room, outside every obstacle)."""
        p = np.asarray(p_m, dtype=float)
        lo, hi = np.array(self.bounds.lo_m), np.array(self.bounds.hi_m)
        if not (np.all(p > lo) and np.all(p < hi)):
            return False
        return not any(
            np.all(p >= np.array(o.lo_m)) and np.all(p <= np.array(o.hi_m)) for o in self.obstacles
        )


def load_textures(dirs=DEFAULT_TEXTURE_DIRS, max_count: int = 24) -> np.ndarray:
    """Loads up to max_count PNG photographs (sorted by name) as an (N, H, W, 3) uint8 array.

    Raises FileNotFoundError naming the folders when no image is found, ValueError on mixed sizes.
    """
    from PIL import Image  # imported here: only texture loading needs Pillow

    paths: list[Path] = []
    for d in dirs:
        paths.extend(sorted(Path(d).glob("*.png")))
    if not paths:
        raise FileNotFoundError(f"no texture images (*.png) in {', '.join(str(d) for d in dirs)}")
    # Spread the picks over the sequences so consecutive (near-identical) frames are not all chosen.
    step = max(1, len(paths) // max_count)
    chosen = paths[::step][:max_count]
    images = [np.asarray(Image.open(p).convert("RGB")) for p in chosen]
    shape = images[0].shape
    if any(im.shape != shape for im in images):
        raise ValueError("texture images must all have the same size")
    return np.stack(images)


def default_room(textures: np.ndarray | None = None) -> Room:
    """An 8 m x 6 m x 3 m room (a lab/gym the thesis flights fit in) with a desk-sized box and a
    pillar,
    so the depth image has occluding edges (and Kinect shadows) and the floor map has obstacles."""
    tex = load_textures() if textures is None else textures
    return Room(
        bounds=Box((-4.0, -3.0, 0.0), (4.0, 3.0, 3.0)),
        textures=tex,
        obstacles=[
            Box((1.5, -2.2, 0.0), (2.7, -1.4, 0.75)),  # desk-height crate
            Box((-2.6, 1.6, 0.0), (-2.2, 2.0, 3.0)),
        ],  # floor-to-ceiling pillar
    )
