"""Signed distances between shapes in the ground plane, and a car's clearance from obstacles.

* ``distances``: between each of N cars' K shapes and M shapes, exactly (separating axes and
  closest vertices of rectangles and circles), negative (the penetration depth) where they
  overlap.
* ``clearance``: the smallest distance between a robot's footprint (``projection.footprint``)
  at its pose and the obstacles: pybullet's ``getClosestPoints`` for the car on the ground.

The 2D model of the 3D world: obstacles are vertical prisms from the ground up to
``OBSTACLE_HEIGHT_M``, and the car stands on the ground (base_link at z = 0) with its collision
shapes below the obstacles' tops. Then the 3D distance between a car part and an obstacle is
the 2D distance between their projections (the closest points lie at one height). Where they
overlap, the 3D penetration depth is the smaller of the 2D one and the vertical way out (the
part's top height: 0.05 m for the shipped car's wheels, 0.08 m for its body), which
``clearance`` applies.

Against pybullet (tests/test_planar_geometry.py): ``clearance`` with ``BULLET_BOX_MARGIN_M`` is
pybullet's ``getClosestPoints`` within 1e-5 m (GJK's tolerance); with sharp corners (the
default) within 2 (sqrt(2) - 1) ``BULLET_BOX_MARGIN_M`` = 0.83 mm.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from smartcar_gym.sim.planar.projection import Footprint
from smartcar_gym.sim.planar.shapes import (
    BOX,
    OBSTACLE_HEIGHT_M,
    Shapes2D,
    checked_poses,
    is_number,
)

#: pybullet's collision margin of boxes (URDF ``<box>`` and ``createCollisionShape``): their
#: sides are where written, their vertical edges rounded with this radius
BULLET_BOX_MARGIN_M = 0.001


def distances(a: Shapes2D, b: Shapes2D, box_margin: float = 0.0) -> np.ndarray:
    """``(N, K, M)``: the signed distance between each of N cars' K shapes ``a`` and M shapes
    ``b`` (either may be N = 1): the smallest distance (m) where they are apart, minus the
    penetration depth (the shortest move that parts them) where they overlap; inf where either
    is padding. Exact for rectangles and circles (separating axes and closest vertices).

    ``box_margin`` (m) rounds every rectangle's corners with that radius, keeping its sides
    (Bullet's boxes: ``BULLET_BOX_MARGIN_M``); 0: sharp corners.
    """
    _check_margin(box_margin)
    n = max(a.num_cars, b.num_cars)
    k, m = a.num_shapes, b.num_shapes
    ta = np.broadcast_to(_columns(a, box_margin)[:, :, :, None], (7, n, k, m))
    tb = np.broadcast_to(_columns(b, box_margin)[:, :, None, :], (7, n, k, m))
    signed = _signed(ta.reshape(7, -1), tb.reshape(7, -1)).reshape(n, k, m)
    return np.where(a.valid[:, :, None] & b.valid[:, None, :], signed, np.inf)


def _check_margin(box_margin: Any) -> None:
    if not (is_number(box_margin) and 0.0 <= box_margin < math.inf):
        raise ValueError(f"box_margin must be a number of metres >= 0, got {box_margin!r}")


def _columns(shapes: Shapes2D, margin: float) -> np.ndarray:
    """``(7, N, M)``: each shape's centre x, y, (cos, sin), and the half extents of its core
    rectangle (a circle's: 0) and the radius that grows the core into the shape."""
    box = shapes.kind == BOX
    grown = np.where(box, np.minimum(margin, shapes.half.min(axis=-1)), shapes.half[..., 0])
    core = np.where(box[..., None], shapes.half - grown[..., None], 0.0)
    return np.stack([shapes.centre[..., 0], shapes.centre[..., 1], shapes.rotation[..., 0],
                     shapes.rotation[..., 1], core[..., 0], core[..., 1], grown])


def _kept(shapes: Shapes2D, what: str, margin: float) -> np.ndarray:
    """``shapes``' bounding radii (``"radius"``) or ``_columns`` with ``margin``, computed
    once per ``Shapes2D`` (a batch's obstacles stay the same from step to step)."""
    kept = shapes.__dict__.setdefault("_kept", {})
    key = (what, margin)
    if key not in kept:
        kept[key] = (shapes.bounding_radius() if what == "radius"
                     else _columns(shapes, margin))
        kept[key].setflags(write=False)
    return kept[key]


def _signed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Signed distances between shapes given as ``_columns`` ``(7, L)`` pairwise (``(L,)``): the
    cores' (separating axes where they overlap, nearest corners where apart) less the radii."""
    ax0, ay0, ca, sa, hax, hay, ra = a
    bx0, by0, cb, sb, hbx, hby, rb = b
    dx, dy = bx0 - ax0, by0 - ay0
    cos = ca * cb + sa * sb  # of the angle from a's frame to b's
    sin = ca * sb - sa * cb
    abs_cos, abs_sin = np.abs(cos), np.abs(sin)
    # b's centre in a's frame, a's centre in b's frame
    ax, ay = ca * dx + sa * dy, ca * dy - sa * dx
    bx, by = -(cb * dx + sb * dy), sb * dx - cb * dy
    # separating axes: the gap along each rectangle's two axes (max: -depth when overlapping)
    gap = np.maximum(
        np.maximum(np.abs(ax) - hax - hbx * abs_cos - hby * abs_sin,
                   np.abs(ay) - hay - hbx * abs_sin - hby * abs_cos),
        np.maximum(np.abs(bx) - hbx - hax * abs_cos - hay * abs_sin,
                   np.abs(by) - hby - hax * abs_sin - hay * abs_cos))
    # apart: the nearest of either rectangle's corners to the other rectangle
    corner = np.minimum(_corners_to_box(bx, by, hax, hay, cos, -sin, hbx, hby),
                        _corners_to_box(ax, ay, hbx, hby, cos, sin, hax, hay))
    return np.where(gap > 0.0, corner, gap) - ra - rb


def _corners_to_box(qx: np.ndarray, qy: np.ndarray, hx: np.ndarray, hy: np.ndarray,
                    c: np.ndarray, s: np.ndarray, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
    """Distance from the nearest corner of a rectangle (centre ``q``, half extents ``h``, turned
    by (``c``, ``s``), all in the frame of an axis-aligned box of half extents ``b`` about the
    origin) to that box."""
    ex, ey = hx * c, hx * s  # the rectangle's half axes in the box's frame
    fx, fy = -hy * s, hy * c
    best = None
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):  # the four corners, not cars or beams
        px = np.abs(qx + sx * ex + sy * fx) - bx
        py = np.abs(qy + sx * ey + sy * fy) - by
        d = np.hypot(np.maximum(px, 0.0), np.maximum(py, 0.0))
        best = d if best is None else np.minimum(best, d)
    return best


def clearance(footprint: Footprint, poses: Any, shapes: Shapes2D, max_distance: float, *,
              height: float | None = OBSTACLE_HEIGHT_M, box_margin: float = 0.0,
              cars: np.ndarray | None = None) -> np.ndarray:
    """``(N,)``: the smallest distance (m) between the footprint with base_link at ``poses``
    (``(N, 3)``: x, y, yaw) and car i's ``shapes`` (N or 1 worlds), negative (the
    penetration depth) where they overlap, at most ``max_distance``: pybullet's
    ``getClosestPoints`` (``sim.obstacles.nearest_distance``) for the car on the ground.
    ``footprint``: every car's, or one per car (``Footprint.stack``, N of them).

    Exact in 2D (``distances``). ``height``: the obstacles are prisms from the ground up to
    it and base_link is on the ground (z = 0), so each part's ``footprint.z_range`` says how
    it meets them: a part within their height gets the 2D distance, its overlap at most the
    vertical way out (its top, or ``height`` minus its bottom), as in 3D; a part wholly above
    them (or below the ground) the hypotenuse of its 2D distance and the height between. None:
    the 2D distance alone.
    ``box_margin``: see ``distances`` (``BULLET_BOX_MARGIN_M`` matches pybullet's rounded box
    edges). ``cars``: a bool mask (N,) of the cars to measure (None: all); the others get
    ``max_distance``, and a measured car's value is the same as without the mask.
    """
    if not (is_number(max_distance) and math.isfinite(max_distance)):
        raise ValueError(f"max_distance must be a finite number of metres, got {max_distance!r}")
    if height is not None and not (is_number(height) and 0.0 < height < math.inf):
        raise ValueError(f"height must be a positive number of metres or None, got {height!r}")
    if not isinstance(footprint, Footprint):
        raise ValueError(f"footprint must be a Footprint, got {type(footprint).__name__}")
    if not isinstance(shapes, Shapes2D):
        raise ValueError(f"shapes must be a Shapes2D, got {type(shapes).__name__}")
    _check_margin(box_margin)
    poses = checked_poses(poses)
    n = len(poses)
    if shapes.num_cars not in (1, n):
        raise ValueError(f"shapes hold {shapes.num_cars} cars' obstacles, poses {n} cars")
    shapes = shapes.broadcast_to(n)
    nearest = np.full(n, float(max_distance))
    if cars is None:  # the measured cars: every row of the arrays, or the listed rows
        rows: Any = slice(None)
        measured = footprint
    elif isinstance(cars, np.ndarray) and cars.dtype == np.bool_ and cars.shape == (n,):
        rows = np.flatnonzero(cars)
        measured = footprint.take(rows)
    else:
        raise ValueError(f"cars must be a bool mask of shape ({n},), got {cars!r}")
    # broad phase: the (car, obstacle) pairs whose bounding circles are within max_distance
    offset = shapes.centre[rows] - poses[rows, None, :2]
    apart = np.hypot(offset[..., 0], offset[..., 1]) - _kept(shapes, "radius", 0.0)[rows]
    pair_row, pair_shape = np.nonzero(shapes.valid[rows]
                                      & (apart < footprint.radius + max_distance))
    pair_car = pair_row if cars is None else rows[pair_row]
    if len(pair_car) == 0:
        return nearest
    # exact: each pair's obstacle against every part of its car's footprint, (pair, part)
    k = footprint.shapes.num_shapes
    parts = np.take(_columns(measured.place(poses[rows]), box_margin), pair_row, axis=1)
    obstacles = _kept(shapes, "columns", box_margin)[:, pair_car, pair_shape]
    signed = _signed(parts.reshape(7, -1), np.repeat(obstacles, k, axis=1)).reshape(-1, k)
    if height is not None:
        z_range = footprint.z_range
        if z_range.ndim == 3:  # a stack: each pair's car's own parts
            z_range = z_range[pair_car]
        low, high = z_range[..., 0], z_range[..., 1]
        gap = np.maximum(np.maximum(low - height, -high), 0.0)  # a part above or below
        signed = np.where(gap > 0.0, np.hypot(np.maximum(signed, 0.0), gap),
                          np.maximum(signed, -np.minimum(high, height - low)))
    np.minimum.at(nearest, pair_car, signed.min(axis=1))
    return nearest
