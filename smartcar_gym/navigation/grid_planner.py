"""A global planner on an occupancy grid, as move_base's (navfn: Dijkstra over a costmap).

The map is a grid of cells holding the distance (m) from each cell's centre to the nearest
obstacle's outline (``distance_grid``, for circles). Cells nearer than ``inflation_m`` (the
robot's radius) are lethal; beyond it a cell costs ``1 + weight * exp(-decay * (d - inflation))``
per metre crossed, so that the path keeps to the middle of a gap, as the costmap's inflation
layer makes navfn's do. ``plan_path`` runs Dijkstra (scipy's) on the 8-connected grid from the
start's cell and returns the cells' centres to the goal's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

_NEIGHBOURS = ((1, 0), (0, 1), (1, 1), (1, -1))  # half of the 8; edges go both ways
#: the most cells a grid may have (a BARN world's arena at 0.02 m: 274,000); Dijkstra's graph
#: takes about 200 bytes a cell
MAX_CELLS = 4_000_000


class NoPathError(RuntimeError):
    """No path between the start and the goal through free cells."""


@dataclass(frozen=True)
class DistanceGrid:
    """``distance[iy, ix]``: metres from the centre of cell (ix, iy) to the nearest obstacle;
    cell (0, 0)'s centre is at ``origin``, cells are ``resolution`` m square."""

    origin: tuple[float, float]
    resolution: float
    distance: np.ndarray

    def cell(self, point: np.ndarray) -> tuple[int, int]:
        """The (ix, iy) cell holding ``point`` (x, y), clipped into the grid."""
        ny, nx = self.distance.shape
        ix = int(round((float(point[0]) - self.origin[0]) / self.resolution))
        iy = int(round((float(point[1]) - self.origin[1]) / self.resolution))
        return min(max(ix, 0), nx - 1), min(max(iy, 0), ny - 1)

    def centre(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """Centres (m) of cells ``(ix, iy)``, as (..., 2)."""
        return np.stack([self.origin[0] + np.asarray(ix) * self.resolution,
                         self.origin[1] + np.asarray(iy) * self.resolution], axis=-1)


def distance_grid(centres: np.ndarray, radii: np.ndarray, low: np.ndarray, high: np.ndarray,
                  resolution: float) -> DistanceGrid:
    """The distance grid of circles (``centres`` (K, 2), ``radii`` (K,), m) over the box from
    ``low`` to ``high`` (x, y); ValueError if that is more than ``MAX_CELLS`` cells."""
    if not resolution > 0:
        raise ValueError(f"resolution must be > 0 m, got {resolution!r}")
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    if not (np.isfinite(low).all() and np.isfinite(high).all() and np.all(high >= low)):
        raise ValueError(f"the grid's box must be finite with high >= low, got low "
                         f"{low.tolist()}, high {high.tolist()}")
    nx, ny = (np.floor((high - low) / resolution) + 1).tolist()
    if nx * ny > MAX_CELLS:
        raise ValueError(f"a grid from {low.tolist()} to {high.tolist()} at {resolution:g} m "
                         f"would have {nx * ny:.3g} cells, more than {MAX_CELLS:,}")
    nx, ny = int(nx), int(ny)
    xs = low[0] + resolution * np.arange(nx)
    ys = low[1] + resolution * np.arange(ny)
    cells = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    radii = np.asarray(radii, dtype=float).reshape(-1)
    out = np.full(len(cells), np.inf)
    for radius in np.unique(radii):  # exact: the nearest centre of each radius
        nearest, _ = cKDTree(centres[radii == radius]).query(cells)
        out = np.minimum(out, nearest - radius)
    return DistanceGrid((float(low[0]), float(low[1])), float(resolution), out.reshape(ny, nx))


def plan_path(grid: DistanceGrid, start: np.ndarray, goal: np.ndarray, inflation_m: float,
              weight: float = 3.0, decay_per_m: float = 20.0) -> np.ndarray:
    """The cheapest 8-connected way (cell centres, (M, 2) m) from ``start``'s cell to
    ``goal``'s, through cells at least ``inflation_m`` from every obstacle. NoPathError if the
    start or the goal is lethal or there is no way."""
    d = grid.distance
    free = d >= inflation_m
    cost = 1.0 + weight * np.exp(-decay_per_m * np.maximum(d - inflation_m, 0.0))
    (sx, sy), (gx, gy) = grid.cell(start), grid.cell(goal)
    for name, (ix, iy), point in (("start", (sx, sy), start), ("goal", (gx, gy), goal)):
        if not free[iy, ix]:
            raise NoPathError(f"the {name} {np.round(point, 3).tolist()} is within "
                              f"{inflation_m:.3f} m of an obstacle (the inflated map)")
    cells = cheapest_cells(cost, free, (sx, sy), (gx, gy), grid.resolution)
    if cells is None:
        raise NoPathError(f"no way from {np.round(start, 3).tolist()} to "
                          f"{np.round(goal, 3).tolist()} keeps {inflation_m:.3f} m from every "
                          "obstacle")
    nx = d.shape[1]
    return grid.centre(cells % nx, cells // nx)


def cheapest_cells(cost: np.ndarray, free: np.ndarray, start: tuple[int, int],
                   goal: tuple[int, int], step: float = 1.0) -> np.ndarray | None:
    """The cheapest 8-connected way between cells ``start`` and ``goal`` (ix, iy) through
    ``free`` cells, as the flat indices (row by row) of its cells, or None if there is none.
    A move between neighbours costs its length (``step`` a side) times the mean of the two
    cells' ``cost``; Dijkstra (scipy's) on the grid's graph."""
    ny, nx = cost.shape
    index = np.arange(nx * ny).reshape(ny, nx)
    rows, cols, weights = [], [], []
    for dx, dy in _NEIGHBOURS:
        ys = slice(max(0, -dy), ny - max(0, dy))
        ys2 = slice(max(0, dy), ny - max(0, -dy))
        xs, xs2 = slice(0, nx - dx), slice(dx, nx)
        both = free[ys, xs] & free[ys2, xs2]
        w = step * math.hypot(dx, dy) * 0.5 * (cost[ys, xs] + cost[ys2, xs2])
        rows.append(index[ys, xs][both])
        cols.append(index[ys2, xs2][both])
        weights.append(w[both])
    rows_a, cols_a = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.concatenate(weights), (rows_a, cols_a)), shape=(nx * ny,) * 2).tocsr()
    source, target = index[start[1], start[0]], index[goal[1], goal[0]]
    dist, previous = dijkstra(graph, directed=False, indices=source, return_predecessors=True)
    if not np.isfinite(dist[target]):
        return None
    cells = [target]
    while cells[-1] != source:
        cells.append(previous[cells[-1]])
    return np.array(cells[::-1])


def path_length(path: np.ndarray) -> float:
    """Length (m) of a polyline (M, 2)."""
    return float(np.sum(np.linalg.norm(np.diff(np.asarray(path, dtype=float), axis=0), axis=1)))
