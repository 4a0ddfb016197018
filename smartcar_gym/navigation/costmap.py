"""move_base's global costmap as the BARN challenge builds it: from the laser alone.

The challenge gives move_base no map (its ``jackal_helper/configs/params``): the global costmap
is a static 40 m x 40 m grid of 0.05 m cells in the odom frame, centred on the start, with an
obstacle layer (``obstacle_range`` 2.5 m, ``raytrace_range`` 3.0 m) and an inflation layer
(``inflation_radius`` 0.30 m, ``cost_scaling_factor`` costmap_2d's default 10), no static
layer, unknown space not tracked (an unseen cell is free). ``CostmapConfig.challenge`` scales
its lengths. ``LaserCostmaps`` holds N such grids, one per car, as costmap_2d's uint8 costs:

* **clearing** (``ObstacleLayer::raytraceFreespace``): every beam clears the cells of the
  Bresenham line (``Costmap2D::raytraceLine``) from the laser's cell towards its return, the
  return's cell included, cut at ``raytrace_range`` and at the grid's edge; a ``+inf`` beam
  (nothing within range_max) is a return at ``raytrace_range``, as ``inf_is_valid: true`` has it
  (docs/barn.md says why); ``-inf`` and NaN beams are dropped;
* **marking** (``ObstacleLayer::updateBounds``), after all the clearing: a return nearer than
  ``obstacle_range`` makes its cell LETHAL (254);
* **inflation** (``InflationLayer``): a cell within ``inflation_radius`` of a lethal cell costs
  ``computeCost`` of its distance to the nearest one: 253 within the inscribed radius, else
  ``int(252 exp(-cost_scaling_factor (d - inscribed_radius)))``, at cell-centre distances.
  After each update only the cells an update can have changed are inflated again (numpy: the
  box of the touched cells, grown by the inflation radius; the compiled loops: the box of the
  cells whose mark changed, so grown, nothing when none did), from the lethal cells within
  the inflation radius of them: the costs are always the whole grid's inflation, exactly.

Two ways, the same arrays bit for bit (``tests/test_costmap.py``): numpy, and numba's loops
(the ``fast`` extra) where installed, both in ``costmap_loops.py``. The beams' end cells, their
cut and the boxes are float work: numba's loops do numpy's operations in numpy's order, with
numpy's own cosines, sines and hypot; clearing, marking and inflating are integer work.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from smartcar_gym import checks
from smartcar_gym.navigation.costmap_loops import (
    COMPILED,
    FREE,
    INSCRIBED,
    LETHAL,
    beams_to_cells,
    beams_to_cells_compiled,
    compiled_update,
    inflate_numpy,
    trace_cells,
)
from smartcar_gym.navigation.grid_planner import MAX_CELLS
from smartcar_gym.parallel import run_chunks

#: the most cells all of a ``LaserCostmaps``' grids may hold together (two bytes a cell)
MAX_TOTAL_CELLS = 256_000_000
# the challenge's values (the Jackal's, unscaled; jackal_helper/configs/params)
CHALLENGE_RESOLUTION = 0.05  # global_costmap_params.yaml
CHALLENGE_SIZE = 40.0  # global_costmap_params.yaml: width, height; origin -20, -20
CHALLENGE_OBSTACLE_RANGE = 2.5  # costmap_common_params.yaml
CHALLENGE_RAYTRACE_RANGE = 3.0  # costmap_common_params.yaml
CHALLENGE_INFLATION_RADIUS = 0.30  # costmap_common_params.yaml: inflater_layer
CHALLENGE_COST_SCALING_FACTOR = 10.0  # not set there: InflationPlugin.cfg's default (1/m)
#: the padded footprint's inscribed radius: footprint y +-0.165 m, footprint_padding 0.1 m
CHALLENGE_INSCRIBED_RADIUS = 0.265


def cells_of(length: float, resolution: float, ceil: bool) -> int:
    """``length / resolution`` as a whole count of cells, up (``ceil``, costmap_2d's
    ``cellDistance``) or down (its map size): a quotient within 1e-9 of a whole number is
    that number, so that a scaled config has the unscaled one's counts (40 m / 0.05 m is
    800 cells; 0.4186 x 40 m / (0.4186 x 0.05 m) is 799.9999999999999)."""
    q = length / resolution
    if abs(q - round(q)) <= 1e-9 * max(1.0, q):
        return int(round(q))
    return int(math.ceil(q)) if ceil else int(math.floor(q))


@dataclass(frozen=True)
class CostmapConfig:
    """The global costmap's parameters (m, 1/m); the defaults are the challenge's (the
    Jackal's, unscaled). The grid is ``size`` m square in the car's odom frame, its lower-left
    corner at ``origin`` (None: ``(-size / 2, -size / 2)``, centred on the start, as the
    challenge's ``origin_x, origin_y: -20``)."""

    #: cell side (m); the challenge's 0.05
    resolution: float = CHALLENGE_RESOLUTION
    #: the grid's width and height (m); the challenge's 40
    size: float = CHALLENGE_SIZE
    #: returns nearer than this mark their cell (m); the challenge's 2.5
    obstacle_range: float = CHALLENGE_OBSTACLE_RANGE
    #: beams clear cells up to this far (m); the challenge's 3.0
    raytrace_range: float = CHALLENGE_RAYTRACE_RANGE
    #: cells within this of a lethal one cost (m); the challenge's 0.30
    inflation_radius: float = CHALLENGE_INFLATION_RADIUS
    #: the cost's decay beyond the inscribed radius (1/m); costmap_2d's default 10
    cost_scaling_factor: float = CHALLENGE_COST_SCALING_FACTOR
    #: the car's inscribed radius (m): cells within it of a lethal one are INSCRIBED; the
    #: challenge's padded footprint's 0.265
    inscribed_radius: float = CHALLENGE_INSCRIBED_RADIUS
    #: the grid's lower-left corner (x, y) in the odom frame (m); None: centred on the start
    origin: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("resolution", "size", "obstacle_range", "raytrace_range",
                     "inflation_radius", "cost_scaling_factor"):
            checks.positive_number(f"costmap {name}", getattr(self, name))
        checks.non_negative_number("costmap inscribed_radius", self.inscribed_radius)
        if self.inscribed_radius > self.inflation_radius:
            raise ValueError(f"costmap inscribed_radius {self.inscribed_radius!r} m must not "
                             f"exceed inflation_radius {self.inflation_radius!r} m")
        if self.origin is not None:
            checks.number_pair("costmap origin", self.origin)
        n = self.size / self.resolution
        if n * n > MAX_CELLS:
            raise ValueError(f"costmap size {self.size!r} m at resolution {self.resolution!r} "
                             f"m is {n * n:.3g} cells, more than {MAX_CELLS:,}")
        if self.cells < 1:
            raise ValueError(f"costmap size {self.size!r} m is less than one cell of "
                             f"{self.resolution!r} m")

    @classmethod
    def challenge(cls, scale: float = 1.0, inscribed_radius: float | None = None
                  ) -> CostmapConfig:
        """The challenge's global costmap for a world ``scale`` times as big: lengths times
        ``scale``, ``cost_scaling_factor`` over it; ``inscribed_radius``: the car's (None: the
        challenge's padded footprint's, scaled)."""
        checks.positive_number("costmap scale", scale)
        return cls(resolution=CHALLENGE_RESOLUTION * scale, size=CHALLENGE_SIZE * scale,
                   obstacle_range=CHALLENGE_OBSTACLE_RANGE * scale,
                   raytrace_range=CHALLENGE_RAYTRACE_RANGE * scale,
                   inflation_radius=CHALLENGE_INFLATION_RADIUS * scale,
                   cost_scaling_factor=CHALLENGE_COST_SCALING_FACTOR / scale,
                   inscribed_radius=(CHALLENGE_INSCRIBED_RADIUS * scale
                                     if inscribed_radius is None else inscribed_radius))

    @property
    def cells(self) -> int:
        """Cells a side (costmap_2d's ``(unsigned)(width / resolution)``)."""
        return cells_of(self.size, self.resolution, ceil=False)

    @property
    def corner(self) -> tuple[float, float]:
        """The grid's lower-left corner in the odom frame (m)."""
        if self.origin is None:
            return -0.5 * self.size, -0.5 * self.size
        return float(self.origin[0]), float(self.origin[1])

    @property
    def raytrace_cells(self) -> int:
        """``raytrace_range`` in cells, rounded up (costmap_2d's ``cellDistance``)."""
        return cells_of(self.raytrace_range, self.resolution, ceil=True)

    @property
    def inflation_cells(self) -> int:
        """``inflation_radius`` in cells, rounded up (costmap_2d's ``cellDistance``)."""
        return cells_of(self.inflation_radius, self.resolution, ceil=True)

    def cost_of(self, distance_cells: np.ndarray) -> np.ndarray:
        """costmap_2d's ``InflationLayer::computeCost``: the cost (uint8) of a cell
        ``distance_cells`` cells from the nearest lethal one."""
        d = np.asarray(distance_cells, dtype=float)
        metres = d * self.resolution
        decayed = (INSCRIBED - 1) * np.exp(-1.0 * self.cost_scaling_factor
                                           * (metres - self.inscribed_radius))
        cost = np.where(metres <= self.inscribed_radius, INSCRIBED,
                        np.trunc(np.minimum(decayed, INSCRIBED - 1)))
        return np.where(d == 0, LETHAL, cost).astype(np.uint8)

    def cost_table(self) -> np.ndarray:
        """The cost (uint8) of a cell at squared distance ``d2`` cells (0 to
        ``inflation_cells ** 2``) from the nearest lethal cell: ``cost_table()[d2]``."""
        r = self.inflation_cells
        return self.cost_of(np.sqrt(np.arange(r * r + 1, dtype=float)))

    def kernel(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The inflation's offsets ``(dx, dy, cost)``: every cell offset within
        ``inflation_cells`` of a lethal cell (costmap_2d's ``enqueue`` test), its cost."""
        r = self.inflation_cells
        dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
        d2 = dx * dx + dy * dy
        keep = d2 <= r * r
        return (dx[keep].astype(np.int64), dy[keep].astype(np.int64),
                self.cost_table()[d2[keep]])


def laser_poses(base_poses: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """The laser frame's poses (K, 3: x, y, theta) in odom of base_link's ``base_poses``,
    the laser at ``mount`` (its 4 x 4 pose in base_link)."""
    p = np.asarray(base_poses, dtype=float).reshape(-1, 3)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    return np.stack([p[:, 0] + c * mount[0, 3] - s * mount[1, 3],
                     p[:, 1] + s * mount[0, 3] + c * mount[1, 3],
                     p[:, 2] + math.atan2(mount[1, 0], mount[0, 0])], axis=-1)


class LaserCostmaps:
    """N cars' global costmaps built from their lasers (module docstring): ``costs(car)``
    (uint8, ``[iy, ix]``, FREE 0 to LETHAL 254) and the obstacle layer's marks under them,
    each grid in its car's odom frame. ``compiled``: numba's loops (None: where installed;
    False: numpy); ``threads``: the compiled loops' cars split over that many threads."""

    def __init__(self, config: CostmapConfig, n: int, compiled: bool | None = None,
                 threads: int = 1) -> None:
        checks.positive_int("costmap cars", n)
        cells = config.cells
        if n * cells * cells > MAX_TOTAL_CELLS:
            raise ValueError(f"costmap cars: {n} grids of {cells} x {cells} cells are more than "
                             f"{MAX_TOTAL_CELLS:,} cells")
        self.compiled = COMPILED if compiled is None else bool(compiled)
        if self.compiled and not COMPILED:
            raise RuntimeError('the compiled costmap needs numba: pip install "smartcar-gym[fast]"')
        self.config = config
        self.n = n
        self.threads = checks.positive_int("costmap threads", threads)
        self._marks = np.zeros((n, cells, cells), dtype=np.uint8)
        self._costs = np.zeros((n, cells, cells), dtype=np.uint8)
        self._table = config.cost_table()
        # the kernel's half width at each row offset |dy| <= r: its offsets are the
        # (dx, dy) with |dx| <= half[|dy|] (the compiled update stamps it row by row)
        kdx, kdy, _ = config.kernel()
        self._half = np.array([kdx[kdy == dy].max() for dy in range(config.inflation_cells + 1)],
                              dtype=np.int64)
        # per car, a box (x_lo, y_lo, x_hi, y_hi, exclusive) holding every cell that has had a
        # cost since its reset: the union of its updates' boxes
        self._bounds = np.tile(np.array([cells, cells, 0, 0], dtype=np.int64), (n, 1))

    def _cars(self, cars: Sequence[int] | np.ndarray) -> np.ndarray:
        return checks.car_indices("costmap", cars, self.n)

    def _car(self, car: int) -> int:
        return checks.car_index("costmap", car, self.n)

    def reset(self, cars: Sequence[int] | np.ndarray) -> None:
        """Clears the grids of ``cars``: nothing seen."""
        idx = self._cars(cars)
        for car in idx.tolist():  # every cell outside a car's bounds is FREE already
            x_lo, y_lo, x_hi, y_hi = self._bounds[car].tolist()
            self._marks[car, y_lo:y_hi, x_lo:x_hi] = FREE
            self._costs[car, y_lo:y_hi, x_lo:x_hi] = FREE
        self._bounds[idx] = (self.config.cells, self.config.cells, 0, 0)

    def update(self, cars: Sequence[int] | np.ndarray, poses: np.ndarray, ranges: np.ndarray,
               angles: np.ndarray, mount: np.ndarray | None = None,
               threads: int | None = None) -> None:
        """Clears, marks and inflates the grids of ``cars`` (K,) from one scan each:
        ``ranges`` (K, B) m (REP 117: ``+inf`` nothing in range, ``-inf`` too close) at beam
        ``angles`` (B,) rad, taken at ``poses`` (K, 3: x, y, theta in the odom frame) of the
        laser frame, or of base_link with the laser at ``mount`` (its 4 x 4 pose there);
        ``threads``: the compiled loops' (None: ``self.threads``)."""
        threads = self.threads if threads is None else checks.positive_int("costmap threads",
                                                                            threads)
        idx = self._cars(cars)
        poses = np.asarray(poses, dtype=np.float64).reshape(len(idx), 3)
        if mount is not None:
            poses = laser_poses(poses, np.asarray(mount, dtype=float))
        angles = np.asarray(angles, dtype=np.float64).reshape(-1)
        ranges = np.asarray(ranges).reshape(len(idx), len(angles))
        if len(idx) == 0:
            return
        beams = (beams_to_cells_compiled(self.config, poses, ranges, angles)
                 if self.compiled else beams_to_cells(self.config, poses, ranges, angles))
        touched = (beams.box[:, 0] < beams.box[:, 2]) & (beams.box[:, 1] < beams.box[:, 3])
        old = self._bounds[idx[touched]]
        new = beams.box[touched]
        self._bounds[idx[touched]] = np.concatenate(
            [np.minimum(old[:, :2], new[:, :2]), np.maximum(old[:, 2:], new[:, 2:])], axis=1)
        r = self.config.inflation_cells
        if not self.compiled:
            k, xs, ys = trace_cells(beams)
            self._marks[idx[k], ys, xs] = FREE
            k, b = np.nonzero(beams.mark)
            self._marks[idx[k], beams.my[k, b], beams.mx[k, b]] = LETHAL
            for row, car in enumerate(idx.tolist()):
                inflate_numpy(self._marks[car], self._costs[car], beams.box[row], r,
                               self._table)
            return

        def work(a: int, b: int) -> None:
            compiled_update(idx[a:b], beams.x0[a:b], beams.y0[a:b], beams.ok[a:b],
                            beams.x1[a:b], beams.y1[a:b], beams.end[a:b], beams.trace[a:b],
                            beams.mx[a:b], beams.my[a:b], beams.mark[a:b], r, self._half,
                            self._table, self._marks, self._costs)

        run_chunks(work, len(idx), threads)

    def clear_outside(self, cars: Sequence[int] | np.ndarray, centres: np.ndarray,
                      side: float) -> None:
        """clear_costmap_recovery's reset of the grids of ``cars`` (K,): the obstacle layer's
        marks outside the square of ``side`` m about ``centres`` (K, 2, m, odom frame) set FREE
        (``ClearCostmapRecovery::clearMap``: the corners' cells by ``worldToMapNoBounds``,
        truncated; ``CostmapLayer::clearArea`` keeps only the cells strictly between them),
        then the whole grid inflated again. The same for numpy and numba (the marks and costs
        are shared; the inflation is ``inflate_numpy``'s, which the compiled update equals)."""
        idx = self._cars(cars)
        centres = np.asarray(centres, dtype=float).reshape(len(idx), 2)
        x0, y0 = self.config.corner
        res, n = self.config.resolution, self.config.cells
        cells = np.arange(n)
        for car, (cx, cy) in zip(idx.tolist(), centres.tolist(), strict=True):
            start = (int((cx - side / 2 - x0) / res), int((cy - side / 2 - y0) / res))
            end = (int((cx - side / 2 + side - x0) / res), int((cy - side / 2 + side - y0) / res))
            keep_x = (cells > start[0]) & (cells < end[0])
            keep_y = (cells > start[1]) & (cells < end[1])
            self._marks[car][~(keep_y[:, None] & keep_x[None, :])] = FREE
            inflate_numpy(self._marks[car], self._costs[car], np.array([0, 0, n, n]),
                          self.config.inflation_cells, self._table)

    def costs(self, car: int) -> np.ndarray:
        """Car ``car``'s costs ``[iy, ix]`` (uint8; a read-only view)."""
        view = self._costs[self._car(car)]
        view.flags.writeable = False
        return view

    def costs_at(self, cars: np.ndarray, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """The costs of cells ``(ix, iy)`` of the grids of ``cars`` (equal-length integer
        arrays, one cell each; uint8)."""
        return self._costs[cars, iy, ix]

    def bounds(self, car: int) -> tuple[int, int, int, int]:
        """A box ``(x_lo, y_lo, x_hi, y_hi)`` (cells, exclusive; empty when ``x_lo >= x_hi``)
        holding every cell of car ``car``'s grid that has had a cost since its reset: the union
        of its updates' boxes. Outside it every cell is FREE."""
        x_lo, y_lo, x_hi, y_hi = self._bounds[self._car(car)].tolist()
        return x_lo, y_lo, x_hi, y_hi

    def lethal(self, car: int) -> np.ndarray:
        """Car ``car``'s lethal cells ``[iy, ix]``: the obstacle layer's marks (bool)."""
        return self._marks[self._car(car)] == LETHAL

    def world_to_cell(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cells ``(ix, iy, inside)`` holding ``points`` (..., 2: x, y, m in the odom
        frame; costmap_2d's ``worldToMap``: ``inside`` false off the grid)."""
        p = np.asarray(points, dtype=float)
        x0, y0 = self.config.corner
        fx = np.floor((p[..., 0] - x0) / self.config.resolution)
        fy = np.floor((p[..., 1] - y0) / self.config.resolution)
        n = self.config.cells
        inside = (fx >= 0) & (fy >= 0) & (fx < n) & (fy < n)
        return (np.where(inside, fx, 0).astype(np.int64),
                np.where(inside, fy, 0).astype(np.int64), inside)

    def cell_of(self, x: float, y: float) -> tuple[int, int] | None:
        """``world_to_cell`` of one point (x, y; m, odom frame) on Python's floats (the same
        arithmetic): its cell ``(ix, iy)``, None off the grid."""
        x0, y0 = self.config.corner
        res, n = self.config.resolution, self.config.cells
        fx, fy = math.floor((float(x) - x0) / res), math.floor((float(y) - y0) / res)
        return (fx, fy) if 0 <= fx < n and 0 <= fy < n else None

    def cell_to_world(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """The centres (..., 2, m in the odom frame) of cells ``(ix, iy)`` (``mapToWorld``)."""
        x0, y0 = self.config.corner
        res = self.config.resolution
        return np.stack([x0 + (np.asarray(ix) + 0.5) * res,
                         y0 + (np.asarray(iy) + 0.5) * res], axis=-1)
