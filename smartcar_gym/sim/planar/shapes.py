"""Convex shapes in the ground plane, as numpy arrays over N cars: the planar world's obstacles.

``Shapes2D``: M convex shapes per car, ``(N, M)`` arrays padded with a validity mask; a shape is
an oriented rectangle (``BOX``) or a circle (``CIRCLE``). ``Shapes2D.from_layouts`` reads the
nav task's obstacle layouts (``envs.tasks.obstacles.Obstacle``). The argument checks the 2D
geometry's functions share (``checked_poses``, ``checked_points``, ``is_number``) are here too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: shape kinds
BOX, CIRCLE = 0, 1
#: ``Obstacle.shape`` -> kind (an upright cylinder's projection is a circle)
OBSTACLE_KINDS = {"box": BOX, "cylinder": CIRCLE}
#: the nav task's obstacles' height (m): ``envs.world.OBSTACLE_HEIGHT_M``
OBSTACLE_HEIGHT_M = 0.3


@dataclass(frozen=True, eq=False)
class Shapes2D:
    """M convex shapes per car, ``(N, M)``, padded: the shapes of car i are ``valid[i]``.

    A shape is an oriented rectangle (``kind`` ``BOX``: ``half`` = half its length along its own
    x and half its width) or a circle (``CIRCLE``: ``half`` = (radius, radius)), centred on
    ``centre`` (m, world frame) and turned by the yaw whose (cos, sin) is ``rotation``. Padding
    entries (``valid`` False) are never hit and never near.
    """

    kind: np.ndarray  # (N, M) int8
    centre: np.ndarray  # (N, M, 2) m
    rotation: np.ndarray  # (N, M, 2) cos, sin of the yaw
    half: np.ndarray  # (N, M, 2) m
    valid: np.ndarray  # (N, M) bool

    def __post_init__(self) -> None:
        kind = np.asarray(self.kind)
        if kind.ndim != 2:
            raise ValueError(f"kind must be an (N, M) array, got shape {kind.shape}")
        n, m = kind.shape
        arrays = {"kind": kind.astype(np.int8), "valid": np.asarray(self.valid, dtype=bool)}
        for name in ("centre", "rotation", "half"):
            arrays[name] = np.asarray(getattr(self, name), dtype=float)
            if arrays[name].shape != (n, m, 2):
                raise ValueError(f"{name} must be an (N, M, 2) = {(n, m, 2)} array, got shape "
                                 f"{arrays[name].shape}")
        if arrays["valid"].shape != (n, m):
            raise ValueError(f"valid must be an (N, M) = {(n, m)} array, got shape "
                             f"{arrays['valid'].shape}")
        valid = arrays["valid"]
        if not np.isin(arrays["kind"][valid], (BOX, CIRCLE)).all():
            raise ValueError(f"kind must be BOX ({BOX}) or CIRCLE ({CIRCLE}) for valid shapes")
        for name in ("centre", "rotation", "half"):
            if not np.isfinite(arrays[name][valid]).all():
                raise ValueError(f"{name} must be finite for valid shapes")
        if not (arrays["half"][valid] > 0).all():
            raise ValueError("half extents / radii (half) must be > 0 for valid shapes")
        norm = np.hypot(arrays["rotation"][..., 0], arrays["rotation"][..., 1])
        if not np.allclose(norm[valid], 1.0, rtol=0.0, atol=1e-9):
            raise ValueError("rotation must hold unit (cos yaw, sin yaw) vectors")
        circle = valid & (arrays["kind"] == CIRCLE)
        if not np.array_equal(arrays["half"][circle, 0], arrays["half"][circle, 1]):
            raise ValueError("a circle's half must be (radius, radius)")
        for name, value in arrays.items():
            value = value.view()  # read-only, the caller's array untouched
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def take(self, rows: np.ndarray, m: int) -> Shapes2D:
        """Cars ``rows``' first ``m`` shapes (already checked: no checks run again)."""
        return Shapes2D.derived(*(getattr(self, name)[rows, :m] for name in
                                  ("kind", "centre", "rotation", "half", "valid")))

    @staticmethod
    def derived(kind: np.ndarray, centre: np.ndarray, rotation: np.ndarray, half: np.ndarray,
                valid: np.ndarray) -> Shapes2D:
        """Shapes made from checked ones by taking rows or moving them rigidly (``take``,
        ``Footprint.place``): the checks are not run again, the arrays are made read-only."""
        out = object.__new__(Shapes2D)
        for name, value in zip(("kind", "centre", "rotation", "half", "valid"),
                               (kind, centre, rotation, half, valid), strict=True):
            value = value.view()
            value.setflags(write=False)
            object.__setattr__(out, name, value)
        return out

    @classmethod
    def from_arrays(cls, kind: Any, centre: Any, yaw: Any, half: Any,
                    valid: Any = None) -> Shapes2D:
        """Shapes from ``(N, M)`` kinds and yaws (rad), ``(N, M, 2)`` centres and half extents
        (a circle's: (r, r) or (r, anything)); ``valid`` defaults to all."""
        kind = np.asarray(kind, dtype=np.int8)
        yaw = np.asarray(yaw, dtype=float)
        half = np.array(half, dtype=float)
        if half.shape[:2] == kind.shape and half.ndim == 3:
            half[..., 1] = np.where(kind == CIRCLE, half[..., 0], half[..., 1])
        valid = np.ones(kind.shape, dtype=bool) if valid is None else valid
        return cls(kind, centre, np.stack([np.cos(yaw), np.sin(yaw)], axis=-1), half, valid)

    @classmethod
    def from_layouts(cls, layouts: Sequence[Sequence[Any]],
                     num_shapes: int | None = None) -> Shapes2D:
        """The obstacles of N cars: ``layouts[i]`` is car i's sequence of ``Obstacle`` (a box:
        ``size`` = (length, width), turned by ``yaw``; an upright cylinder: ``size`` =
        (diameter,)). Padded to ``num_shapes`` (default: the longest layout)."""
        if isinstance(layouts, str | bytes) or not isinstance(layouts, Sequence):
            raise ValueError(f"layouts must be a sequence of obstacle layouts (one per car), "
                             f"got {type(layouts).__name__}")
        longest = max((len(layout) for layout in layouts), default=0)
        m = longest if num_shapes is None else num_shapes
        if not (isinstance(m, int) and m >= longest):
            raise ValueError(f"num_shapes must be an int >= the longest layout ({longest}), "
                             f"got {num_shapes!r}")
        n = len(layouts)
        kind = np.zeros((n, m), dtype=np.int8)
        centre, half = np.zeros((n, m, 2)), np.zeros((n, m, 2))
        yaw, valid = np.zeros((n, m)), np.zeros((n, m), dtype=bool)
        for i, layout in enumerate(layouts):
            for j, obstacle in enumerate(layout):
                where = f"layouts[{i}][{j}]"
                shape = getattr(obstacle, "shape", None)
                if shape not in OBSTACLE_KINDS:
                    raise ValueError(f"{where} must be an Obstacle of shape "
                                     f"{tuple(OBSTACLE_KINDS)}, got {obstacle!r}")
                size = tuple(obstacle.size)
                if len(size) != (2 if shape == "box" else 1):
                    raise ValueError(f"{where}: a {shape}'s size is "
                                     f"{'(length, width)' if shape == 'box' else '(diameter,)'}"
                                     f", got {size!r}")
                kind[i, j] = OBSTACLE_KINDS[shape]
                centre[i, j] = obstacle.position
                half[i, j] = (size[0] / 2.0, size[-1] / 2.0)
                yaw[i, j] = obstacle.yaw if shape == "box" else 0.0
                valid[i, j] = True
        return cls(kind, centre, np.stack([np.cos(yaw), np.sin(yaw)], axis=-1), half, valid)

    @classmethod
    def from_layout(cls, layout: Sequence[Any]) -> Shapes2D:
        """One world's obstacles (a single env): ``from_layouts([layout])``, N = 1."""
        return cls.from_layouts([layout])

    @property
    def num_cars(self) -> int:
        return self.kind.shape[0]

    @property
    def num_shapes(self) -> int:
        return self.kind.shape[1]

    def bounding_radius(self) -> np.ndarray:
        """``(N, M)``: radius of the circle about each centre that holds the shape (-1: padding)."""
        radius = np.where(self.kind == BOX, np.hypot(self.half[..., 0], self.half[..., 1]),
                          self.half[..., 0])
        return np.where(self.valid, radius, -1.0)

    def relative_to(self, poses: Any) -> Shapes2D:
        """These shapes (N or 1 cars') in the frames at ``poses`` (``(N, 3)``: x, y, yaw in m,
        m, rad), e.g. each car's laser frame: a scan is then ``cast`` from the origin along
        beams shared by every car, the faster form (the same ranges to ~1e-15 m)."""
        poses = checked_poses(poses)
        shapes = self.broadcast_to(len(poses))
        c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        dx = shapes.centre[..., 0] - poses[:, :1]
        dy = shapes.centre[..., 1] - poses[:, 1:2]
        rc, rs = shapes.rotation[..., 0], shapes.rotation[..., 1]
        return Shapes2D(shapes.kind, np.stack([c * dx + s * dy, c * dy - s * dx], axis=-1),
                        np.stack([c * rc + s * rs, c * rs - s * rc], axis=-1), shapes.half,
                        shapes.valid)

    def broadcast_to(self, n: int) -> Shapes2D:
        """These shapes for ``n`` cars: N = n as is, or N = 1 repeated (read-only views)."""
        if self.num_cars == n:
            return self
        if self.num_cars != 1:
            raise ValueError(f"shapes hold {self.num_cars} cars' obstacles, expected {n} or 1")
        fields = ("kind", "centre", "rotation", "half", "valid")
        return Shapes2D(**{f: np.broadcast_to(getattr(self, f), (n, *getattr(self, f).shape[1:]))
                           for f in fields})


# -- argument checks ---------------------------------------------------------------------------
def is_number(value: Any) -> bool:
    """Whether ``value`` is a real number (not a bool)."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool)


def checked_points(name: str, value: Any) -> np.ndarray:
    """``value`` as an (N, 2) array of finite points; ValueError naming ``name`` otherwise."""
    points = np.asarray(value, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"{name} must be an (N, 2) array of x, y (m), got shape {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError(f"{name} must be finite")
    return points


def checked_poses(value: Any) -> np.ndarray:
    """``value`` as an (N, 3) array of finite poses x, y, yaw; ValueError otherwise."""
    poses = np.asarray(value, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must be an (N, 3) array of x, y, yaw (m, m, rad), got shape "
                         f"{poses.shape}")
    if not np.isfinite(poses).all():
        raise ValueError("poses must be finite")
    return poses
