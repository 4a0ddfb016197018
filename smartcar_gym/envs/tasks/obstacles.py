"""Obstacle layouts: boxes and cylinders on the ground, drawn at random or given by the user.

Pure geometry and sampling (no simulator): an ``Obstacle`` knows its distance to points, an
``ObstacleField`` draws a layout from a generator that leaves room around the start and the
goal, and ``read_layout`` checks a user's layout (a list of dicts, or a YAML/JSON file of one).
"""

from __future__ import annotations

import json
import math
import numbers
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from smartcar_gym import checks

SHAPES = ("box", "cylinder")
LAYOUT_KEYS = ("shape", "position", "size", "yaw")
#: free space (m) kept between two drawn obstacles' enclosing circles: the car (0.2 m wide)
#: fits through every gap
MIN_GAP_M = 0.3
MAX_TRIES = 2000  # draws per layout before giving up


@dataclass(frozen=True)
class Obstacle:
    """A ``box`` (``size`` = length along its x, width along its y, turned by ``yaw``) or an
    upright ``cylinder`` (``size`` = (diameter,)), centred on ``position`` (m, world frame)."""

    shape: str
    position: tuple[float, float]
    size: tuple[float, ...]
    yaw: float = 0.0

    @property
    def radius(self) -> float:
        """Radius of the smallest circle around the centre that holds the obstacle (m)."""
        return math.hypot(*self.size) / 2.0 if self.shape == "box" else self.size[0] / 2.0

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance (m) from ``(..., 2)`` points to the obstacle's outline, < 0 inside."""
        d = np.asarray(points, dtype=float) - np.asarray(self.position)
        if self.shape == "cylinder":
            return np.linalg.norm(d, axis=-1) - self.size[0] / 2.0
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], -1)
        excess = np.abs(local) - np.asarray(self.size) / 2.0
        outside = np.linalg.norm(np.maximum(excess, 0.0), axis=-1)
        return outside + np.minimum(np.max(excess, axis=-1), 0.0)

    def to_dict(self) -> dict[str, Any]:
        """The layout entry of this obstacle (what ``read_layout`` reads back)."""
        return {"shape": self.shape, "position": list(self.position), "size": list(self.size),
                "yaw": self.yaw}


@dataclass(frozen=True)
class ObstacleField:
    """Draws ``count`` obstacles centred in the square ``|x|, |y| <= half_extent_m``.

    Shapes are boxes or cylinders with equal chance; box sides and cylinder diameters are
    uniform in ``size_range_m``, box headings uniform. Every obstacle keeps ``clearance_m`` of
    free space around a circle of ``robot_radius_m`` at the start and at the goal, and
    ``MIN_GAP_M`` from the other obstacles' enclosing circles.
    """

    count: int = 6
    size_range_m: tuple[float, float] = (0.15, 0.35)
    clearance_m: float = 0.2
    half_extent_m: float = 2.0
    robot_radius_m: float = 0.15

    def __post_init__(self) -> None:
        if not (isinstance(self.count, numbers.Integral) and not isinstance(self.count, bool)
                and self.count >= 0):
            raise ValueError(f"obstacles must be a whole number >= 0, got {self.count!r}")
        low, high = self.size_range_m
        if not 0 < low <= high:
            raise ValueError(f"obstacle_size must be (min, max) metres with 0 < min <= max, got "
                             f"{self.size_range_m!r}")
        if not (checks.is_real(self.clearance_m) and math.isfinite(self.clearance_m)
                and self.clearance_m >= 0):
            raise ValueError(f"obstacle_clearance must be a number of metres >= 0, got "
                             f"{self.clearance_m!r}")

    @property
    def keep_out_m(self) -> float:
        """Distance from the start and the goal (m) that obstacles stay out of."""
        return self.robot_radius_m + self.clearance_m

    def sample(self, rng: np.random.Generator, start: np.ndarray,
               goal: np.ndarray) -> tuple[Obstacle, ...]:
        """A layout drawn with ``rng`` (RuntimeError if ``MAX_TRIES`` draws cannot place it)."""
        placed: list[Obstacle] = []
        low, high = self.size_range_m
        for _ in range(MAX_TRIES):
            if len(placed) == self.count:
                break
            xy = rng.uniform(-self.half_extent_m, self.half_extent_m, 2)
            if rng.integers(2) == 0:
                candidate = Obstacle("box", (float(xy[0]), float(xy[1])),
                                     tuple(float(v) for v in rng.uniform(low, high, 2)),
                                     float(rng.uniform(-math.pi, math.pi)))
            else:
                candidate = Obstacle("cylinder", (float(xy[0]), float(xy[1])),
                                     (float(rng.uniform(low, high)),))
            if self._fits(candidate, placed, start, goal):
                placed.append(candidate)
        if len(placed) < self.count:
            raise RuntimeError(
                f"could not place {self.count} obstacles of {low:g}-{high:g} m in the "
                f"{2 * self.half_extent_m:g} m square with {self.clearance_m:g} m of clearance "
                f"around start and goal in {MAX_TRIES} draws (placed {len(placed)}): lower "
                "obstacles, obstacle_size or obstacle_clearance"
            )
        return tuple(placed)

    def _fits(self, candidate: Obstacle, placed: Sequence[Obstacle], start: np.ndarray,
              goal: np.ndarray) -> bool:
        if np.min(candidate.distance(np.stack([start, goal]))) < self.keep_out_m:
            return False
        centre = np.asarray(candidate.position)
        return all(np.linalg.norm(centre - np.asarray(o.position)) - candidate.radius - o.radius
                   >= MIN_GAP_M for o in placed)


def clearance(obstacles: Sequence[Obstacle], point: np.ndarray) -> float:
    """Distance (m) from ``point`` to the nearest obstacle's outline (inf if there are none)."""
    return min((float(o.distance(point)) for o in obstacles), default=math.inf)


# -- user layouts ----------------------------------------------------------------------------
def read_layout(value: Any, name: str = "obstacles") -> tuple[Obstacle, ...]:
    """A user's layout: a list of ``{"shape", "position", "size", "yaw"}`` dicts (or of
    ``Obstacle``s), or the path of a YAML/JSON file holding such a list (alone or under an
    ``obstacles`` key).

    ``name`` says where the value came from in error messages.
    """
    if isinstance(value, str | os.PathLike):
        return _read_file(Path(value), name)
    if isinstance(value, Mapping) or not isinstance(value, Sequence) or isinstance(value, bytes):
        raise ValueError(f"{name} must be a list of obstacles ({{'shape': 'box' or 'cylinder', "
                         f"'position': [x, y], 'size': [...], 'yaw': rad}}) or the path of a "
                         f"YAML/JSON file of one, got {type(value).__name__}: {value!r}")
    return tuple(_obstacle(item, f"{name}[{i}]") for i, item in enumerate(value))


def _read_file(path: Path, name: str) -> tuple[Obstacle, ...]:
    where = f"{name} file {path}"
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no such file")
    text = path.read_text(encoding="utf-8")
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as err:
        raise ValueError(f"{where}: not valid {'JSON' if path.suffix == '.json' else 'YAML'}: "
                         f"{err}") from None
    if isinstance(data, Mapping):
        if set(data) != {"obstacles"}:
            raise ValueError(f"{where}: expected a list of obstacles, or a mapping with the one "
                             f"key 'obstacles', got the keys {sorted(map(str, data))}")
        data = data["obstacles"]
    if not isinstance(data, list):
        raise ValueError(f"{where}: expected a list of obstacles, got {type(data).__name__}")
    return tuple(_obstacle(item, f"{path}: obstacles[{i}]") for i, item in enumerate(data))


def _obstacle(item: Any, where: str) -> Obstacle:
    if isinstance(item, Obstacle):  # one read already
        return item
    if not isinstance(item, Mapping):
        raise ValueError(f"{where} must be a mapping with keys shape, position, size (and yaw), "
                         f"got {item!r}")
    unknown = sorted(set(map(str, item)) - set(LAYOUT_KEYS))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; an obstacle has "
                         f"{', '.join(LAYOUT_KEYS)}")
    missing = [k for k in ("shape", "position", "size") if k not in item]
    if missing:
        raise ValueError(f"{where}: missing {', '.join(missing)}")
    shape = item["shape"]
    if shape not in SHAPES:
        raise ValueError(f"{where}: shape must be one of {SHAPES}, got {shape!r}")
    position = _numbers(item["position"], 2, f"{where}: position", "[x, y] in metres")
    size = item["size"]
    if shape == "cylinder" and checks.is_real(size):
        size = [size]
    wanted = 2 if shape == "box" else 1
    size = _numbers(size, wanted, f"{where}: size",
                    "[length, width] in metres" if shape == "box" else "[diameter] in metres")
    if min(size) <= 0:
        raise ValueError(f"{where}: size must be positive metres, got {list(size)}")
    yaw = item.get("yaw", 0.0)
    if not (checks.is_real(yaw) and math.isfinite(yaw)):
        raise ValueError(f"{where}: yaw must be a finite number of radians, got {yaw!r}")
    return Obstacle(shape, (position[0], position[1]), size, float(yaw))


def _numbers(value: Any, count: int, where: str, expected: str) -> tuple[float, ...]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if (isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence)
            or len(value) != count
            or not all(checks.is_real(v) and math.isfinite(v) for v in value)):
        raise ValueError(f"{where} must be {expected}, got {value!r}")
    return tuple(float(v) for v in value)
