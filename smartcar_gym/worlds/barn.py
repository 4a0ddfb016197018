"""The 300 BARN worlds (Benchmark for Autonomous Robot Navigation) and the challenge's protocol.

The worlds ship as ``worlds/barn_data/barn_worlds.npz`` (MIT licence beside it): every cylinder
of the challenge's Gazebo worlds and its reference paths in grid cells (``README.md`` there).
``load_worlds`` reads and checks a file once (what it may declare is bounded: ``MAX_*``;
docs/barn.md, "World files"); ``BarnWorlds.world(i)`` is world i in the challenge's frame (m),
``test_worlds`` and ``train_worlds`` the file's split. ``to_car_frame`` puts challenge
coordinates into the frame the car starts in (the start at the origin, its heading +x),
scaled: the Jackal's width to the gaps becomes the car's.
"""

from __future__ import annotations

import functools
import math
import os
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from smartcar_gym import checks
from smartcar_gym.navigation.grid_planner import path_length

#: the shipped world file
DATA_FILE = "barn_worlds.npz"
ARRAYS = ("centres", "radii", "offsets", "paths", "path_offsets")
#: optional arrays: a file's own test and training worlds (indices; each defaults to all)
SPLIT = ("test_worlds", "train_worlds")
N_WORLDS = 300
#: the challenge's test set: every sixth world; the other 250 are for training
TEST_WORLDS: tuple[int, ...] = tuple(range(0, N_WORLDS, 6))
TRAIN_WORLDS: tuple[int, ...] = tuple(i for i in range(N_WORLDS) if i % 6)

# -- what a world file may declare (a file is data: it cannot make us allocate without bound) --
MAX_WORLDS = 10_000
MAX_CYLINDERS_PER_WORLD = 10_000  # the shipped worlds: 181-365
MAX_PATH_CELLS_PER_WORLD = 10_000  # the shipped paths: a few dozen cells
MAX_ROWS = 1_000_000  # rows of centres, radii or paths in one file (16 MB of float64 pairs)

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
#: the arena's half size around the start (the task's: 2.5 x the goal's distance, halved); a
#: cylinder's centre and its whole outline lie within it
ARENA_HALF_M = 1.25 * math.dist(START_XY, GOAL_XY)


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
    """The worlds of one file (checked: ``BarnWorldError`` naming the file, the array and what
    was expected); ``world(i)`` checks ``i``. ``test_worlds`` and ``train_worlds`` are the
    file's split: ``split`` if given, else the file's ``test_worlds`` and ``train_worlds``
    arrays, each all the worlds where the file has none."""

    def __init__(self, arrays: dict[str, np.ndarray], source: str,
                 split: tuple[Sequence[int], Sequence[int]] | None = None) -> None:
        self.source = source
        _check_arrays(arrays, f"BARN world file {source}")
        self._a = arrays
        every = tuple(range(len(self)))
        if split is None:
            split = tuple(every if arrays.get(key) is None else arrays[key].tolist()
                          for key in SPLIT)
        #: the worlds a benchmark runs by default, and those a reset draws from
        self.test_worlds, self.train_worlds = (tuple(int(i) for i in part) for part in split)

    def __len__(self) -> int:
        return len(self._a["offsets"]) - 1

    def world(self, index: object) -> BarnWorld:
        """World ``index`` (BarnWorldError naming it if it is not an integer, or is out of
        range)."""
        if not checks.is_whole(index):
            raise BarnWorldError(f"BARN world {index!r} is not a world index: expected an "
                                 f"integer 0 to {len(self) - 1}, got {type(index).__name__} "
                                 f"({self.source})")
        if not 0 <= int(index) < len(self):
            raise BarnWorldError(f"BARN world {int(index)} is out of range: the worlds are 0 to "
                                 f"{len(self) - 1} ({self.source})")
        i = int(index)
        a = self._a
        lo, hi = a["offsets"][i], a["offsets"][i + 1]
        plo, phi = a["path_offsets"][i], a["path_offsets"][i + 1]
        return BarnWorld(i, a["centres"][lo:hi], a["radii"][lo:hi], a["paths"][plo:phi])


def default_path() -> Path:
    """Where the shipped world file is."""
    return Path(str(resources.files("smartcar_gym") / "worlds" / "barn_data" / DATA_FILE))


#: each array's kinds of numbers (numpy dtype kinds), columns and most rows
_LAYOUT = {"centres": ("if", 2, MAX_ROWS), "radii": ("if", None, MAX_ROWS),
           "offsets": ("iu", None, MAX_WORLDS + 1), "paths": ("iuf", 2, MAX_ROWS),
           "path_offsets": ("iu", None, MAX_WORLDS + 1),
           "test_worlds": ("iu", None, MAX_WORLDS), "train_worlds": ("iu", None, MAX_WORLDS)}
_KINDS = {"i": "integers", "u": "integers", "f": "floats"}


def _check_header(where: str, key: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    """BarnWorldError unless array ``key`` declares the numbers and the shape it may have."""
    kinds, columns, rows = _LAYOUT[key]
    expected = " or ".join(dict.fromkeys(_KINDS[k] for k in kinds))
    if dtype.kind not in kinds or dtype.hasobject:
        raise BarnWorldError(f"{where}: {key} must hold {expected}, got dtype {dtype}")
    want = (rows,) if columns is None else (rows, columns)
    if len(shape) != len(want) or (columns is not None and shape[1] != columns):
        raise BarnWorldError(f"{where}: {key} must have shape "
                             f"{'(n,)' if columns is None else f'(n, {columns})'}, got {shape}")
    if shape[0] > rows:
        raise BarnWorldError(f"{where}: {key} declares {shape[0]} rows, more than the "
                             f"{rows} a world file may have")


def _check_arrays(a: dict[str, np.ndarray], where: str) -> None:
    """BarnWorldError (one line naming the array or the world) unless the arrays are worlds:
    offsets from 0 to K rising, each world 1 to 10,000 cylinders of a finite radius > 0 inside
    the arena and 1 to 10,000 finite path cells, the split's worlds distinct and in range."""
    for key, value in a.items():
        if value is not None:
            _check_header(where, key, value.shape, value.dtype)
    for key, count, most in (("offsets", len(a["centres"]), MAX_CYLINDERS_PER_WORLD),
                             ("path_offsets", len(a["paths"]), MAX_PATH_CELLS_PER_WORLD)):
        offsets = a[key]
        if len(offsets) < 2 or offsets[0] != 0 or offsets[-1] != count:
            raise BarnWorldError(f"{where}: {key} must run from 0 to the {count} rows with "
                                 f"at least one world, got {_brief(offsets)}")
        sizes = np.diff(offsets)
        bad = np.flatnonzero((sizes < 1) | (sizes > most))
        if len(bad):
            what = "cylinders" if key == "offsets" else "path cells"
            raise BarnWorldError(f"{where}: world {bad[0]} has {sizes[bad[0]]} {what}; a "
                                 f"world has 1 to {most}")
    if len(a["offsets"]) != len(a["path_offsets"]):
        raise BarnWorldError(f"{where}: offsets ({len(a['offsets'])}) and path_offsets "
                             f"({len(a['path_offsets'])}) must be as long (one more than the "
                             "worlds)")
    if len(a["radii"]) != len(a["centres"]):
        raise BarnWorldError(f"{where}: radii must have one row per row of centres "
                             f"({len(a['centres'])}), got {len(a['radii'])}")
    world_of = np.repeat(np.arange(len(a["offsets"]) - 1), np.diff(a["offsets"]))
    for key, bad in (
            ("centres", ~np.isfinite(a["centres"]).all(axis=1)),
            ("radii", ~(np.isfinite(a["radii"]) & (a["radii"] > 0))),
            ("centres", np.any(np.abs(a["centres"] - START_XY) + a["radii"][:, None]
                               > ARENA_HALF_M, axis=1))):
        if bad.any():
            k = int(np.argmax(bad))
            why = (f"a cylinder (centre {a['centres'][k].tolist()}, radius {a['radii'][k]}) "
                   f"reaches outside the arena, {ARENA_HALF_M:g} m around the start "
                   f"{START_XY}" if key == "centres" and np.isfinite(a["centres"][k]).all()
                   and np.isfinite(a["radii"][k]) and a["radii"][k] > 0
                   else f"{key} must be finite{' and > 0' if key == 'radii' else ''}, got "
                        f"{a[key][k].tolist()}")
            raise BarnWorldError(f"{where}: world {world_of[k]}: {why}")
    if not np.isfinite(a["paths"]).all():
        path_of = np.repeat(np.arange(len(a["path_offsets"]) - 1), np.diff(a["path_offsets"]))
        k = int(np.argmax(~np.isfinite(a["paths"]).all(axis=1)))
        raise BarnWorldError(f"{where}: world {path_of[k]}: paths must be finite, got "
                             f"{a['paths'][k].tolist()}")
    n = len(a["offsets"]) - 1
    for key in SPLIT:
        chosen = a.get(key)
        if chosen is not None and (len(chosen) == 0 or len(set(chosen.tolist())) != len(chosen)
                                   or chosen.min() < 0 or chosen.max() >= n):
            raise BarnWorldError(f"{where}: {key} must be distinct worlds 0 to {n - 1}, at "
                                 f"least one, got {_brief(chosen)}")


def _brief(values: np.ndarray) -> str:
    """At most six of ``values``, for a message."""
    shown = values[:6].tolist()
    return f"{shown}{' ...' if len(values) > 6 else ''} ({len(values)} values)"


def _read(path: str, where: str) -> dict[str, np.ndarray]:
    """The arrays of the npz ``path``: each one's header checked before its data is read (so a
    declared shape cannot make us allocate), never unpickled."""
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            members = {name.removesuffix(".npy"): name for name in archive.namelist()}
            missing = [key for key in ARRAYS if key not in members]
            if missing:
                raise BarnWorldError(f"{where}: not a readable npz with the arrays "
                                     f"{', '.join(ARRAYS)} (missing {', '.join(missing)})")
            for key in (*ARRAYS, *(k for k in SPLIT if k in members)):
                with archive.open(members[key]) as f:
                    version = np.lib.format.read_magic(f)
                    read_header = {(1, 0): np.lib.format.read_array_header_1_0,
                                   (2, 0): np.lib.format.read_array_header_2_0}.get(version)
                    if read_header is None:
                        raise ValueError(f"{key}: npy format version {version} (1.0 or 2.0 "
                                         "expected)")
                    shape, _, dtype = read_header(f)
                _check_header(where, key, shape, dtype)
                with archive.open(members[key]) as f:
                    arrays[key] = np.lib.format.read_array(f, allow_pickle=False)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as err:
        if isinstance(err, BarnWorldError):
            raise
        raise BarnWorldError(f"{where}: not a readable npz with the arrays "
                             f"{', '.join(ARRAYS)} ({type(err).__name__}: {err})") from None
    return arrays


@functools.lru_cache(maxsize=4)
def _load(path: str) -> BarnWorlds:
    where = f"BARN world file {path}"
    if not os.path.isfile(path):
        raise BarnWorldError(f"{where}: no such file")
    arrays = _read(path, where)
    shipped = os.path.realpath(path) == os.path.realpath(default_path())
    return BarnWorlds(arrays, path, (TEST_WORLDS, TRAIN_WORLDS) if shipped else None)


def load_worlds(path: str | os.PathLike | None = None) -> BarnWorlds:
    """The worlds of ``path`` (default: the shipped file, with the challenge's split), read and
    checked once per path; one line for a ``path`` that is no path (``world_file``)."""
    if path is not None and (not isinstance(path, str | os.PathLike) or not os.fspath(path)):
        raise TypeError(f"world_file must be a file path (or None for the shipped worlds), got "
                        f"{type(path).__name__}: {path!r}")
    return _load(str(default_path() if path is None else Path(path)))
