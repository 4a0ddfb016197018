"""Horizontal rays against the planar world's shapes, exactly: the laser and ``cast_rays``.

* ``cast``: B rays of each of N cars against ``shapes.Shapes2D``, exactly (ray vs oriented
  rectangle, ray vs circle), nearest hit per ray; a ray that starts inside a shape does not hit
  that shape (Bullet's rule, as pybullet's ``rayTestBatch``).
* ``ray_hits``: the same for 3D rays of one world, as the ``sim.rays.RayHits`` that
  ``sim.rays.cast_rays`` returns.

Against the other engines (tests/test_planar_geometry.py): ``cast`` is exact (MuJoCo's analytic
``mj_ray`` within 1e-12 m); pybullet's ``rayTestBatch`` is not: its hit points lie up to 1 mm
outside the surfaces (its convex cast's tolerance; exact on most box faces: 97 % of box hits
agree within 1e-6 m, 3 % of cylinder hits), so its ranges are up to 1 mm / cos(incidence)
short, and rays grazing an outline (< 0.1 %) may differ in what they hit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from smartcar_gym.sim.planar.raycast_jit import COMPILED, cast_loops
from smartcar_gym.sim.planar.shapes import CIRCLE, OBSTACLE_HEIGHT_M, Shapes2D, checked_points
from smartcar_gym.sim.rays import RayHits

#: candidate (car, beam, shape) triples per block of the ray cast's broad phase (memory bound)
_BLOCK = 1 << 18
_TINY = 1e-300  # stands in for a zero direction component (1 / _TINY is finite)


@dataclass(frozen=True, eq=False)
class RayCast:
    """What each of B rays of N cars hit first: ``distance`` along the ray (m; ``max_range``
    where nothing) and the index of the shape hit (``shape``: 0..M-1 into the ``Shapes2D``,
    -1 none)."""

    distance: np.ndarray  # (N, B) m
    shape: np.ndarray  # (N, B) int
    max_range: np.ndarray  # broadcastable to (N, B), m

    @property
    def hit(self) -> np.ndarray:
        """True where the ray hit a shape."""
        return self.shape >= 0

    @property
    def fraction(self) -> np.ndarray:
        """``distance / max_range``: pybullet's hit fraction (1 where nothing was hit)."""
        with np.errstate(divide="ignore", invalid="ignore"):  # a hit at 0 of a 0 m ray: 1
            return np.where(self.hit, np.nan_to_num(self.distance / self.max_range, nan=1.0),
                            1.0)


def cast(origins: Any, directions: Any, max_range: Any, shapes: Shapes2D,
         compiled: bool | None = None, threads: int = 1) -> RayCast:
    """Cast B rays from each of N cars' ``origins`` (``(N, 2)``, m) against ``shapes``.

    ``directions``: world-frame angles (rad) ``(B,)`` or ``(N, B)``, or unit vectors
    ``(1, B, 2)`` or ``(N, B, 2)``. ``max_range``: the rays' length (m), a number or an array
    broadcastable to ``(N, B)``. ``shapes``: N cars' (or one world's, N = 1) shapes. Exact: ray
    vs oriented rectangle (slabs) and vs circle, nearest hit along each ray; a shape touched
    at a single point or along a side counts as hit (up to rounding); a ray starting strictly
    inside a shape does not hit it (Bullet's rule). Ties go to the lower shape index.

    Vectorised over cars x beams x shapes: a broad phase keeps the (car, shape, beam) triples
    whose beam points into the shape's bounding cone (one matrix product per block of cars
    that fits the cache; blocks, not cars, are looped over), the exact tests run on those
    alone. A laser's scans are fastest in each car's laser frame, the beams shared:
    ``cast(np.zeros((N, 2)), beam_angles, range_max, shapes.relative_to(laser_poses))``
    (no ``(N, B)`` sines and cosines; benchmarks/planar_geometry.py).

    ``compiled``: None, numba's loops where installed (``raycast_jit``: the same answers bit
    for bit, found by angle instead of by blocks), the cars split over ``threads``; False,
    numpy.
    """
    origins = checked_points("origins", origins)
    n = len(origins)
    beams = _directions(directions, n)  # (N or 1, 2, B)
    b = beams.shape[2]
    reach = np.asarray(max_range, dtype=float)
    try:
        reach_nb = np.broadcast_to(reach, (n, b))
    except ValueError:
        raise ValueError(f"max_range must be a number or broadcast to (N, B) = {(n, b)}, got "
                         f"shape {reach.shape}") from None
    if not (np.isfinite(reach_nb).all() and (reach_nb >= 0).all()):
        raise ValueError("max_range must be finite and >= 0")
    if not isinstance(shapes, Shapes2D):
        raise ValueError(f"shapes must be a Shapes2D, got {type(shapes).__name__}")
    shapes = shapes.broadcast_to(n)
    m = shapes.num_shapes
    distance = np.array(reach_nb, dtype=float)
    hit_shape = np.full((n, b), m, dtype=np.int64)  # m: none yet
    if n == 0 or b == 0 or m == 0:
        return RayCast(distance, np.full((n, b), -1, dtype=np.int64), reach)
    if COMPILED if compiled is None else compiled:
        cast_loops(origins, beams, reach_nb, shapes, distance, hit_shape, threads)
    else:
        _cast_blocks(origins, beams, reach, reach_nb, shapes, distance, hit_shape)
    hit_shape[hit_shape == m] = -1  # m: none
    return RayCast(distance, hit_shape, reach)


def _cast_blocks(origins: np.ndarray, beams: np.ndarray, reach: np.ndarray,
                 reach_nb: np.ndarray, shapes: Shapes2D, distance: np.ndarray,
                 hit_shape: np.ndarray) -> None:
    """``cast`` in numpy, into ``distance`` (N, B, preset to the reach) and ``hit_shape``
    (N, B, preset to M): a broad phase per block of cars, the exact tests on what it keeps."""
    n, b, m = len(origins), beams.shape[2], shapes.num_shapes
    flat_distance, flat_shape = distance.reshape(-1), hit_shape.reshape(-1)
    table, cone, cos = _pair_table(origins, shapes, reach_nb.max(axis=1))
    flat_beams = beams.reshape(-1)
    shared = len(beams) == 1
    flat_reach = np.ascontiguousarray(reach_nb).reshape(-1) if reach.ndim else float(reach)
    step = max(1, _BLOCK // (b * m))
    for start in range(0, n, step):  # blocks of cars that fit the cache, not cars
        stop = min(n, start + step)
        # broad phase: the beams within each shape's bounding cone, (car, shape, beam) C order
        dots = np.matmul(cone[start:stop], beams if shared else beams[start:stop])
        index = np.flatnonzero(dots >= cos[start:stop])
        if index.size == 0:
            continue
        pair = index // b  # (car, shape) within the block
        beam = index - pair * b
        pair += start * m
        car = pair // m
        ray = car * b + beam
        at = beam if shared else car * (2 * b) + beam  # the beam's x in flat_beams
        t = _exact_hits(np.take(table, pair, axis=1), np.take(flat_beams, at),
                        np.take(flat_beams, at + b),
                        flat_reach if reach.ndim == 0 else np.take(flat_reach, ray))
        np.minimum.at(flat_distance, ray, t)  # the nearest hit per ray
        won = np.flatnonzero(t == flat_distance[ray])
        np.minimum.at(flat_shape, ray[won], pair[won] - car[won] * m)  # ties: the lower index


def _pair_table(origins: np.ndarray, shapes: Shapes2D,
                reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (car, shape), what the exact tests need (``(10, N * M)``: the shape's (cos, sin),
    the offsets of its slabs from the origin in its frame, its centre from the origin, its
    radius squared, is-circle) and its bounding cone seen from the origin: the unit vector to
    the centre (``(N, M, 2)``) and the cosine of the half angle (``(N, M, 1)``; 2 where no
    beam can hit it: padding, beyond ``reach`` (N,), or holding the origin (Bullet's rule))."""
    n, m = shapes.kind.shape
    w = shapes.centre - origins[:, None, :]  # (N, M, 2)
    wx, wy = w[..., 0], w[..., 1]
    c, s = shapes.rotation[..., 0], shapes.rotation[..., 1]
    hx, hy = shapes.half[..., 0], shapes.half[..., 1]
    px, py = -(c * wx + s * wy), s * wx - c * wy  # the origin in the shape's frame
    circle = shapes.kind == CIRCLE
    inside = np.where(circle, px * px + py * py < hx * hx,
                      (np.abs(px) < hx) & (np.abs(py) < hy))
    table = np.stack([c, s, -hx - px, hx - px, -hy - py, hy - py, wx, wy, hx * hx,
                      circle.astype(float)]).reshape(10, n * m)
    centre = np.hypot(wx, wy)
    radius = shapes.bounding_radius() * (1.0 + 1e-9) + 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = w / centre[..., None]
        cos = np.sqrt(np.maximum(1.0 - (radius / centre) ** 2, 0.0)) - 1e-12
    cos = np.where(centre <= radius, -2.0, cos)  # the origin in the bounding circle
    cos = np.where(~shapes.valid | inside | (centre - radius > reach[:, None]), 2.0, cos)
    unit = np.where(np.isfinite(unit), unit, 0.0)
    return table, unit, cos[..., None]


def _exact_hits(row: np.ndarray, ux: np.ndarray, uy: np.ndarray,
                reach: np.ndarray | float) -> np.ndarray:
    """Distance along each ray to its shape (inf: no hit), for ``(10, K)`` columns of
    ``_pair_table``, ``(K,)`` unit directions and ray lengths; the origin is outside the
    shape."""
    c, s, x0, x1, y0, y1, wx, wy, r2, circle = row
    # rectangle, in its frame: where the ray is within both slabs
    dx = c * ux + s * uy
    dy = c * uy - s * ux
    ix = 1.0 / np.where(dx == 0.0, _TINY, dx)
    iy = 1.0 / np.where(dy == 0.0, _TINY, dy)
    t1, t2, t3, t4 = x0 * ix, x1 * ix, y0 * iy, y1 * iy
    enter = np.maximum(np.minimum(t1, t2), np.minimum(t3, t4))
    leave = np.minimum(np.maximum(t1, t2), np.maximum(t3, t4))
    box = np.where((enter <= leave) & (enter >= 0.0), enter, np.inf)
    # circle, in the world frame: the nearer root along the ray
    across = ux * wy - uy * wx
    disc = r2 - across * across
    first = ux * wx + uy * wy - np.sqrt(np.maximum(disc, 0.0))
    round_ = np.where((disc >= 0.0) & (first >= 0.0), first, np.inf)
    t = np.where(circle > 0.0, round_, box)
    return np.where(t <= reach, t, np.inf)


def ray_hits(starts: Any, ends: Any, shapes: Shapes2D, bodies: Any,
             height: float = OBSTACLE_HEIGHT_M) -> RayHits:
    """``sim.rays.cast_rays`` for one world's obstacles: rays from ``starts`` to ``ends``
    (``(R, 3)``, m, world frame) against ``shapes`` (N = 1), prisms from the ground up to
    ``height``; ``bodies`` (M,) is each shape's body id (what ``RayHits.body`` reports).

    The rays must be horizontal (ValueError otherwise); a ray below the ground or above
    ``height`` hits nothing, and so does a ray of zero length.
    """
    starts = np.asarray(starts, dtype=float)
    ends = np.asarray(ends, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != 3 or starts.shape != ends.shape:
        raise ValueError(f"ray starts and ends must be two (R, 3) arrays, got shapes "
                         f"{starts.shape} and {ends.shape}")
    if not (np.isfinite(starts).all() and np.isfinite(ends).all()):
        raise ValueError("ray starts and ends must be finite")
    if not isinstance(shapes, Shapes2D) or shapes.num_cars != 1:
        raise ValueError("shapes must be one world's Shapes2D (N = 1)")
    bodies = np.asarray(bodies, dtype=int)
    if bodies.shape != (shapes.num_shapes,):
        raise ValueError(f"bodies must be ({shapes.num_shapes},) body ids, one per shape, got "
                         f"shape {bodies.shape}")
    vec = ends - starts
    length = np.hypot(vec[:, 0], vec[:, 1])
    if not (np.abs(vec[:, 2]) <= 1e-9 * np.maximum(1.0, length)).all():
        raise ValueError("rays must be horizontal (start z == end z): the planar geometry "
                         "knows the obstacles' outlines, not their 3D shapes")
    moving = length > 0
    units = np.where(moving[:, None], vec[:, :2] / np.where(moving, length, 1.0)[:, None],
                     [1.0, 0.0])
    if len(starts) and (starts == starts[0]).all():  # one origin: a laser's scan
        found = cast(starts[:1, :2], units[None], length[None], shapes)
    else:
        found = cast(starts[:, :2], units[:, None], length[:, None], shapes)
    within = moving & (starts[:, 2] >= 0.0) & (starts[:, 2] <= height)
    shape = np.where(within, found.shape.reshape(-1), -1)
    hit = shape >= 0
    fraction = np.where(hit, found.distance.reshape(-1) / np.where(moving, length, 1.0), 1.0)
    body = bodies[np.maximum(shape, 0)] if len(bodies) else np.full(len(shape), -1)
    return RayHits(fraction=fraction, body=np.where(hit, body, -1),
                   point=starts + vec * fraction[:, None])


def _directions(value: Any, n: int) -> np.ndarray:
    """``(N or 1, 2, B)``: the x and y of unit vectors given as angles ``(B,)``/``(N, B)`` or
    as ``(1 or N, B, 2)`` unit vectors."""
    directions = np.asarray(value, dtype=float)
    if directions.ndim in (1, 2):
        if directions.ndim == 2 and directions.shape[0] != n:
            raise ValueError(f"directions as angles must be (B,) or (N, B) with N = {n}, got "
                             f"shape {directions.shape}")
        if not np.isfinite(directions).all():
            raise ValueError("directions must be finite")
        angles = directions.reshape(-1 if directions.ndim == 2 else 1, directions.shape[-1])
        return np.stack([np.cos(angles), np.sin(angles)], axis=1)
    if directions.ndim != 3 or directions.shape[2] != 2 or directions.shape[0] not in (1, n):
        raise ValueError(f"directions must be angles (B,) or (N, B), or unit vectors (1, B, 2) "
                         f"or (N, B, 2) with N = {n}, got shape {directions.shape}")
    norm2 = np.einsum("...i,...i->...", directions, directions)
    if not (np.abs(norm2 - 1.0) <= 2e-9).all():
        raise ValueError("directions as vectors must be unit vectors")
    return np.ascontiguousarray(directions.transpose(0, 2, 1))
