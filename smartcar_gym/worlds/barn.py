"""The 300 BARN worlds (Benchmark for Autonomous Robot Navigation) and the challenge's protocol.

The worlds ship as ``worlds/barn_data/barn_worlds.npz`` (MIT licence beside it): every cylinder
of the challenge's Gazebo worlds and its reference paths in grid cells (``README.md`` there).
``load_worlds`` reads the file once; ``BarnWorlds.world(i)`` is world i in the challenge's frame
(m). ``to_car_frame`` puts challenge coordinates into the frame the car starts in (the start at
the origin, its heading +x), scaled: the Jackal's width to the gaps becomes the car's.
"""

from __future__ import annotations

import functools
import math
import os
import zipfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from smartcar_gym.navigation.grid_planner import path_length

#: the shipped world file
DATA_FILE = "barn_worlds.npz"
ARRAYS = ("centres", "radii", "offsets", "paths", "path_offsets")
N_WORLDS = 300
#: the challenge's test set: every sixth world; the other 250 are for training
TEST_WORLDS: tuple[int, ...] = tuple(range(0, N_WORLDS, 6))
TRAIN_WORLDS: tuple[int, ...] = tuple(i for i in range(N_WORLDS) if i % 6)

# -- the challenge's protocol, in its own units (README in barn_data/) --------------------------
JACKAL_WIDTH_M = 0.430
JACKAL_TOP_SPEED_M_S = 2.0
CELL_M = 0.15  # the grid: one cylinder diameter
START_XY = (-2.0, 3.0)
START_YAW = math.pi / 2  # heading +y
GOAL_XY = (-2.0, 13.0)  # 10 m ahead
SUCCESS_RADIUS_M = 1.0
TIMEOUT_S = 100.0
MOVED_M = 0.1  # the run's clock starts once the robot has moved this far


class BarnWorldError(ValueError):
    """A world index out of range, or a world file that is missing or cannot be read."""


@dataclass(frozen=True)
class BarnWorld:
    """World ``index``: its cylinders (centres (K, 2), radii (K,), m) and the challenge's
    reference path (``path_cells``, (M, 2) grid cells), in the challenge's frame."""

    index: int
    centres: np.ndarray
    radii: np.ndarray
    path_cells: np.ndarray

    @property
    def path_points(self) -> np.ndarray:
        """The challenge's path length polyline (m): start, the path's cells, goal."""
        cells = np.asarray(self.path_cells, dtype=float)
        x = cells[:, 0] * CELL_M - CELL_M / 2 - 30 * CELL_M
        y = cells[:, 1] * CELL_M + CELL_M / 2 + 5.0
        return np.vstack([START_XY, np.stack([x, y], axis=1), GOAL_XY])

    @property
    def path_length_m(self) -> float:
        """L: the length of ``path_points`` (m), from which the score's optimal time comes."""
        return path_length(self.path_points)


def to_car_frame(points: np.ndarray, scale: float) -> np.ndarray:
    """Challenge coordinates ``(..., 2)`` (m) in the car's start frame, times ``scale``: the
    start at the origin, the start heading (+y there) along +x."""
    p = np.asarray(points, dtype=float)
    return scale * np.stack([p[..., 1] - START_XY[1], -(p[..., 0] - START_XY[0])], axis=-1)


class BarnWorlds:
    """The worlds of one file; ``world(i)`` checks ``i``."""

    def __init__(self, arrays: dict[str, np.ndarray], source: str) -> None:
        self.source = source
        self._a = arrays

    def __len__(self) -> int:
        return len(self._a["offsets"]) - 1

    def world(self, index: object) -> BarnWorld:
        """World ``index`` (BarnWorldError naming it if it is not a whole number 0-299)."""
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or not (
                0 <= int(index) < len(self)):
            raise BarnWorldError(f"BARN world {index!r} is out of range: the worlds are 0 to "
                                 f"{len(self) - 1} ({self.source})")
        i = int(index)
        a = self._a
        lo, hi = a["offsets"][i], a["offsets"][i + 1]
        plo, phi = a["path_offsets"][i], a["path_offsets"][i + 1]
        return BarnWorld(i, a["centres"][lo:hi], a["radii"][lo:hi], a["paths"][plo:phi])


def default_path() -> Path:
    """Where the shipped world file is."""
    return Path(str(resources.files("smartcar_gym") / "worlds" / "barn_data" / DATA_FILE))


@functools.lru_cache(maxsize=4)
def _load(path: str) -> BarnWorlds:
    where = f"BARN world file {path}"
    if not os.path.isfile(path):
        raise BarnWorldError(f"{where}: no such file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: np.array(data[name]) for name in ARRAYS}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as err:
        raise BarnWorldError(f"{where}: not a readable npz with the arrays "
                             f"{', '.join(ARRAYS)} ({type(err).__name__}: {err})") from None
    offsets, path_offsets = arrays["offsets"], arrays["path_offsets"]
    consistent = (
        arrays["centres"].ndim == 2 and arrays["centres"].shape[1:] == (2,)
        and arrays["radii"].shape == arrays["centres"].shape[:1]
        and arrays["paths"].ndim == 2 and arrays["paths"].shape[1:] == (2,)
        and offsets.shape == path_offsets.shape and offsets.ndim == 1 and len(offsets) >= 2
        and offsets[0] == 0 and offsets[-1] == len(arrays["centres"])
        and np.all(np.diff(offsets) >= 0) and path_offsets[0] == 0
        and path_offsets[-1] == len(arrays["paths"]) and np.all(np.diff(path_offsets) >= 0)
    )
    if not consistent:
        raise BarnWorldError(f"{where}: the arrays do not fit together (centres (K, 2), radii "
                             "(K,), offsets from 0 to K; paths (M, 2), path_offsets from 0 to M)")
    return BarnWorlds(arrays, path)


def load_worlds(path: str | os.PathLike | None = None) -> BarnWorlds:
    """The worlds of ``path`` (default: the shipped file), read once per path."""
    return _load(str(default_path() if path is None else Path(path)))
