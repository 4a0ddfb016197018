"""The navigation task's geometry in the ground plane, as numpy arrays over N cars.

No physics engine: obstacles, laser rays and the car's clearance in 2D, for the planar engine.

* ``Shapes2D``: M convex shapes per car, ``(N, M)`` arrays padded with a validity mask; a shape
  is an oriented rectangle (``BOX``) or a circle (``CIRCLE``). ``Shapes2D.from_layouts`` reads
  the nav task's obstacle layouts (``envs.tasks.obstacles.Obstacle``).
* ``cast``: horizontal rays against them, exactly (ray vs oriented rectangle, ray vs circle),
  nearest hit per ray; a ray that starts inside a shape does not hit that shape (Bullet's rule,
  as pybullet's ``rayTestBatch``). ``ray_hits``: the same for 3D rays of one world, as the
  ``sim.rays.RayHits`` that ``sim.rays.cast_rays`` returns.
* ``footprint``: a robot's collision shapes projected onto the ground, in base_link's frame.
* ``clearance``: the smallest distance between the car's footprint at its pose and the
  obstacles, negative (the penetration depth) where they overlap.

The 2D model of the 3D world: obstacles are vertical prisms from the ground up to
``OBSTACLE_HEIGHT_M`` (``sim.obstacles.add_obstacle``'s boxes and upright cylinders), the laser's
rays are horizontal at a height within them, and the car stands on the ground (base_link at
z = 0) with its collision shapes below the obstacles' tops (the shipped car's reach 0.11 m).
Then a ray hits what its 2D line hits, and the 3D distance between a car part and an obstacle
is the 2D distance between their projections (the closest points lie at one height). Where
they overlap, the 3D penetration depth is the smaller of the 2D one and the vertical way out
(the part's top height: 0.05 m for the shipped car's wheels, 0.08 m for its body), which
``clearance`` applies.

Against pybullet (tests/test_planar_geometry.py): ``clearance`` with ``BULLET_BOX_MARGIN_M``
is pybullet's ``getClosestPoints`` within 1e-5 m (GJK's tolerance); with sharp corners (the
default) within 2 (sqrt(2) - 1) ``BULLET_BOX_MARGIN_M`` = 0.83 mm. ``cast`` is exact (MuJoCo's
analytic ``mj_ray`` within 1e-12 m); pybullet's ``rayTestBatch`` is not: its hit points lie up
to 1 mm outside the surfaces (its convex cast's tolerance; exact on most box faces: 97 % of
box hits agree within 1e-6 m, 3 % of cylinder hits), so its ranges are up to
1 mm / cos(incidence) short, and rays grazing an outline (< 0.1 %) may differ in what they hit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from smartcar_gym.model.contact import simulated_urdf
from smartcar_gym.model.kinematics import link_frames, transform
from smartcar_gym.model.loader import RobotModel
from smartcar_gym.model.urdf import UrdfRobot, parse_urdf
from smartcar_gym.sim.rays import RayHits

#: shape kinds
BOX, CIRCLE = 0, 1
#: ``Obstacle.shape`` -> kind (an upright cylinder's projection is a circle)
OBSTACLE_KINDS = {"box": BOX, "cylinder": CIRCLE}
#: the nav task's obstacles' height (m): ``envs.nav_env.OBSTACLE_HEIGHT_M``
OBSTACLE_HEIGHT_M = 0.3
#: pybullet's collision margin of boxes (URDF ``<box>`` and ``createCollisionShape``): their
#: sides are where written, their vertical edges rounded with this radius
BULLET_BOX_MARGIN_M = 0.001
#: a collision shape's axis counts as vertical / horizontal within this (unit vector component:
#: under a micrometre of difference for shapes under a metre; the projection stays conservative)
AXIS_TOLERANCE = 1e-6
#: candidate (car, beam, shape) triples per block of the ray cast's broad phase (memory bound)
_BLOCK = 1 << 18
_TINY = 1e-300  # stands in for a zero direction component (1 / _TINY is finite)


# -- obstacles as arrays -----------------------------------------------------------------------
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
        poses = _poses(poses)
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


# -- rays ----------------------------------------------------------------------------------
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


def cast(origins: Any, directions: Any, max_range: Any, shapes: Shapes2D) -> RayCast:
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
    """
    origins = _points("origins", origins)
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
    flat_distance, flat_shape = distance.reshape(-1), hit_shape.reshape(-1)
    if n == 0 or b == 0 or m == 0:
        return RayCast(distance, np.full((n, b), -1, dtype=np.int64), reach)

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
    hit_shape[hit_shape == m] = -1
    return RayCast(distance, hit_shape, reach)


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
    return RayHits(fraction=fraction, body=np.where(hit, bodies[np.maximum(shape, 0)], -1),
                   point=starts + vec * fraction[:, None])


# -- distances -----------------------------------------------------------------------------
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
    if not (_is_number(box_margin) and 0.0 <= box_margin < math.inf):
        raise ValueError(f"box_margin must be a number of metres >= 0, got {box_margin!r}")


def _columns(shapes: Shapes2D, margin: float) -> np.ndarray:
    """``(7, N, M)``: each shape's centre x, y, (cos, sin), and the half extents of its core
    rectangle (a circle's: 0) and the radius that grows the core into the shape."""
    box = shapes.kind == BOX
    grown = np.where(box, np.minimum(margin, shapes.half.min(axis=-1)), shapes.half[..., 0])
    core = np.where(box[..., None], shapes.half - grown[..., None], 0.0)
    return np.stack([shapes.centre[..., 0], shapes.centre[..., 1], shapes.rotation[..., 0],
                     shapes.rotation[..., 1], core[..., 0], core[..., 1], grown])


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


# -- the car's footprint -------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Footprint:
    """A robot's collision shapes projected onto the ground, in base_link's frame.

    ``shapes`` (N = 1, K shapes); ``links`` names each shape's link; ``z_range`` (K, 2) is each
    shape's lowest and highest point (m, base_link's z); ``exact`` is False where the
    projection is a bounding rectangle (a tilted shape, a mesh's bounding box).
    """

    shapes: Shapes2D
    links: tuple[str, ...]
    z_range: np.ndarray
    exact: np.ndarray

    @property
    def radius(self) -> float:
        """Radius (m) of the circle about base_link's origin that holds the footprint."""
        local = self.shapes
        return float(np.max(np.hypot(local.centre[0, :, 0], local.centre[0, :, 1])
                            + local.bounding_radius()[0]))

    def place(self, poses: Any) -> Shapes2D:
        """``(N, K)``: the footprint with base_link at each of ``poses`` (``(N, 3)``: x, y, yaw
        in m, m, rad)."""
        poses = _poses(poses)
        c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        local = self.shapes
        lx, ly = local.centre[..., 0], local.centre[..., 1]
        centre = np.stack([poses[:, :1] + c * lx - s * ly, poses[:, 1:2] + s * lx + c * ly], -1)
        rc, rs = local.rotation[..., 0], local.rotation[..., 1]
        rotation = np.stack([c * rc - s * rs, s * rc + c * rs], axis=-1)
        n = len(poses)
        return Shapes2D(np.broadcast_to(local.kind, (n, local.num_shapes)), centre, rotation,
                        np.broadcast_to(local.half, (n, local.num_shapes, 2)),
                        np.broadcast_to(local.valid, (n, local.num_shapes)))


def footprint(robot: RobotModel | UrdfRobot | str, wheel_contact: str = "sphere") -> Footprint:
    """The footprint of ``robot``: a ``RobotModel`` (as simulated: drive wheels as spheres for
    ``wheel_contact="sphere"``, see ``model.contact.simulated_urdf``), a parsed ``UrdfRobot``,
    or URDF text (mesh file names as the model resolved them); ``wheel_contact`` applies to a
    ``RobotModel`` only.

    Every collision shape, with the joints at zero, projected onto the ground plane: a box
    with a vertical axis -> its horizontal rectangle; a sphere -> a circle; a cylinder with a
    vertical axis -> a circle, with a horizontal axis (a wheel) -> the rectangle of its side
    view; a mesh -> its bounding box (OBJ and STL files, scaled), then as a box. A box or
    cylinder tilted otherwise -> the smallest rectangle about its projection along one of its
    projected axes (``exact`` False). A wheel spinning about its axis keeps its projection.
    """
    if isinstance(robot, RobotModel):
        robot = parse_urdf(simulated_urdf(robot, wheel_contact), str(robot.source))
    elif isinstance(robot, str):
        robot = parse_urdf(robot)
    if not isinstance(robot, UrdfRobot):
        raise ValueError(f"robot must be a RobotModel, a UrdfRobot or URDF text, got "
                         f"{type(robot).__name__}")
    frames = link_frames(robot)
    rows, links = [], []
    for name, link in robot.links.items():
        for shape in link.collisions:
            pose = frames[name] @ transform(shape.origin)
            rows.append(_project(shape.geometry, pose, name))
            links.append(name)
    k = len(rows)
    if k == 0:
        raise ValueError(f"robot {robot.name!r} has no collision shapes: no footprint")
    kind, centre, yaw, half, z_range, exact = (np.array(v) for v in zip(*rows, strict=True))
    shapes = Shapes2D.from_arrays(kind[None], centre[None], yaw[None], half[None])
    return Footprint(shapes, tuple(links), z_range.reshape(k, 2), exact.astype(bool))


def _project(geometry: Any, pose: np.ndarray, link: str) -> tuple:
    """(kind, centre, yaw, half, (z low, z high), exact) of one collision shape at ``pose``."""
    rotation, origin = pose[:3, :3], pose[:3, 3]
    if geometry.type == "sphere":
        r = geometry.size[0]
        return CIRCLE, origin[:2], 0.0, (r, r), (origin[2] - r, origin[2] + r), True
    if geometry.type == "cylinder":
        r, length = geometry.size
        axis = rotation[:, 2]
        flat = math.hypot(axis[0], axis[1])
        rise = abs(axis[2])
        z = length / 2.0 * rise + r * flat
        z_range = (origin[2] - z, origin[2] + z)
        if flat <= AXIS_TOLERANCE:
            r += length / 2.0 * flat
            return CIRCLE, origin[:2], 0.0, (r, r), z_range, True
        along = length / 2.0 * flat + r * rise  # the exact support along the projected axis
        return (BOX, origin[:2], math.atan2(axis[1], axis[0]), (along, r), z_range,
                rise <= AXIS_TOLERANCE)
    if geometry.type == "box":
        return _project_box(np.asarray(geometry.size) / 2.0, rotation, origin)
    if geometry.type == "mesh":
        from smartcar_gym.sim.planar.mesh_bounds import mesh_bounds

        low, high = mesh_bounds(geometry.filename, link)
        low, high = low * np.asarray(geometry.size), high * np.asarray(geometry.size)
        low, high = np.minimum(low, high), np.maximum(low, high)  # negative scales
        kind, centre, yaw, half, z_range, _ = _project_box(
            (high - low) / 2.0, rotation, origin + rotation @ ((low + high) / 2.0))
        return kind, centre, yaw, half, z_range, False
    raise ValueError(f"link {link!r}: collision geometry {geometry.type!r} has no footprint")


def _project_box(half: np.ndarray, rotation: np.ndarray, origin: np.ndarray) -> tuple:
    """A box of ``half`` extents turned by ``rotation``: its projection if one of its axes is
    vertical, else the smallest rectangle about its projection along a projected axis."""
    axes = rotation * half  # columns: the box's half axes
    z = float(np.abs(axes[2]).sum())
    z_range = (origin[2] - z, origin[2] + z)
    flat = np.hypot(rotation[0], rotation[1])
    vertical = flat <= AXIS_TOLERANCE
    best = None
    for i in np.flatnonzero(~vertical):  # the box's (at most three) axes, not cars or beams
        u = rotation[:2, i] / flat[i]
        extents = (float(np.abs(u @ axes[:2]).sum()),
                   float(np.abs(np.array([-u[1], u[0]]) @ axes[:2]).sum()))
        if best is None or extents[0] * extents[1] < best[1][0] * best[1][1] - 1e-15:
            best = (math.atan2(u[1], u[0]), extents)
    yaw, extents = best
    return BOX, origin[:2], yaw, extents, z_range, bool(vertical.any())


def clearance(footprint: Footprint, poses: Any, shapes: Shapes2D, max_distance: float, *,
              height: float | None = OBSTACLE_HEIGHT_M, box_margin: float = 0.0) -> np.ndarray:
    """``(N,)``: the smallest distance (m) between the footprint with base_link at ``poses``
    (``(N, 3)``: x, y, yaw) and car i's ``shapes`` (N or 1 worlds), negative (the
    penetration depth) where they overlap, at most ``max_distance``: pybullet's
    ``getClosestPoints`` (``sim.obstacles.nearest_distance``) for the car on the ground.

    Exact in 2D (``distances``). ``height``: the obstacles are prisms from the ground up to
    it and base_link is on the ground (z = 0), so each part's ``footprint.z_range`` says how
    it meets them: a part within their height gets the 2D distance, its overlap at most the
    vertical way out (its top, or ``height`` minus its bottom), as in 3D; a part wholly above
    them (or below the ground) the hypotenuse of its 2D distance and the height between. None:
    the 2D distance alone.
    ``box_margin``: see ``distances`` (``BULLET_BOX_MARGIN_M`` matches pybullet's rounded box
    edges).
    """
    if not (_is_number(max_distance) and math.isfinite(max_distance)):
        raise ValueError(f"max_distance must be a finite number of metres, got {max_distance!r}")
    if height is not None and not (_is_number(height) and 0.0 < height < math.inf):
        raise ValueError(f"height must be a positive number of metres or None, got {height!r}")
    if not isinstance(footprint, Footprint):
        raise ValueError(f"footprint must be a Footprint, got {type(footprint).__name__}")
    if not isinstance(shapes, Shapes2D):
        raise ValueError(f"shapes must be a Shapes2D, got {type(shapes).__name__}")
    _check_margin(box_margin)
    poses = _poses(poses)
    n = len(poses)
    if shapes.num_cars not in (1, n):
        raise ValueError(f"shapes hold {shapes.num_cars} cars' obstacles, poses {n} cars")
    shapes = shapes.broadcast_to(n)
    nearest = np.full(n, float(max_distance))
    # broad phase: the (car, obstacle) pairs whose bounding circles are within max_distance
    offset = shapes.centre - poses[:, None, :2]
    apart = np.hypot(offset[..., 0], offset[..., 1]) - shapes.bounding_radius()
    pair_car, pair_shape = np.nonzero(shapes.valid & (apart < footprint.radius + max_distance))
    if len(pair_car) == 0:
        return nearest
    # exact: each pair's obstacle against every part of its car's footprint, (pair, part)
    k = footprint.shapes.num_shapes
    parts = np.take(_columns(footprint.place(poses), box_margin), pair_car, axis=1)
    obstacles = _columns(shapes, box_margin)[:, pair_car, pair_shape]
    signed = _signed(parts.reshape(7, -1), np.repeat(obstacles, k, axis=1)).reshape(-1, k)
    if height is not None:
        low, high = footprint.z_range[:, 0], footprint.z_range[:, 1]
        gap = np.maximum(np.maximum(low - height, -high), 0.0)  # (K,): a part above or below
        signed = np.where(gap > 0.0, np.hypot(np.maximum(signed, 0.0), gap),
                          np.maximum(signed, -np.minimum(high, height - low)))
    np.minimum.at(nearest, pair_car, signed.min(axis=1))
    return nearest


# -- argument checks -----------------------------------------------------------------------
def _is_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool)


def _points(name: str, value: Any) -> np.ndarray:
    points = np.asarray(value, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"{name} must be an (N, 2) array of x, y (m), got shape {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError(f"{name} must be finite")
    return points


def _poses(value: Any) -> np.ndarray:
    poses = np.asarray(value, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must be an (N, 3) array of x, y, yaw (m, m, rad), got shape "
                         f"{poses.shape}")
    if not np.isfinite(poses).all():
        raise ValueError("poses must be finite")
    return poses


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
