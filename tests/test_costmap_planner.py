"""The laser costmap planner's search (navigation/astar.py) and the box it searches
(``LaserCostmaps.bounds``): the cheapest way, checked against scipy's Dijkstra on the same
graph; numba's and Python's runs of the same code give the same cells."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from smartcar_gym.navigation import astar
from smartcar_gym.navigation.costmap import COMPILED, FREE, CostmapConfig, LaserCostmaps

MOVES = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]


def _grid(seed: int, ny: int = 40, nx: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """navfn-like costs (50 + 0..202, whole) with blobs of obstacles, flat."""
    rng = np.random.default_rng(seed)
    cost = 50.0 + np.trunc(0.8 * rng.integers(0, 253, (ny, nx)) * (rng.random((ny, nx)) < 0.3))
    free = rng.random((ny, nx)) > 0.25
    return cost.ravel(), free.ravel()


def _way_cost(cells: np.ndarray, cost: np.ndarray, nx: int) -> float:
    xs, ys = cells % nx, cells // nx
    steps = np.hypot(np.diff(xs), np.diff(ys))
    assert np.all((steps == 1) | (steps == math.sqrt(2)))  # neighbours, one move each
    return float(np.sum(steps * (cost[cells[:-1]] + cost[cells[1:]])))


def _dijkstra(cost: np.ndarray, free: np.ndarray, nx: int, start: int, goal: int) -> float:
    ny = len(cost) // nx
    rows, cols, weights = [], [], []
    for i in np.flatnonzero(free):
        x, y = i % nx, i // nx
        for dx, dy in MOVES:
            xx, yy = x + dx, y + dy
            if 0 <= xx < nx and 0 <= yy < ny and free[yy * nx + xx]:
                rows.append(i)
                cols.append(yy * nx + xx)
                weights.append(math.hypot(dx, dy) * (cost[i] + cost[yy * nx + xx]))
    graph = coo_matrix((weights, (rows, cols)), shape=(len(cost),) * 2).tocsr()
    return float(dijkstra(graph, indices=start)[goal])


@pytest.mark.parametrize("seed", range(6))
def test_the_search_finds_a_cheapest_way_as_dijkstra_does(seed):
    cost, free = _grid(seed)
    nx = 50
    rng = np.random.default_rng(100 + seed)
    start, goal = rng.choice(np.flatnonzero(free), 2, replace=False)
    best = _dijkstra(cost, free, nx, start, goal)
    cells = astar.search(cost, free, int(start), int(goal), nx, 50.0)
    if not np.isfinite(best):
        assert len(cells) == 0
        return
    assert cells[0] == start and cells[-1] == goal and free[cells].all()
    assert _way_cost(cells, cost, nx) == pytest.approx(best, rel=1e-12)


@pytest.mark.skipif(not COMPILED, reason="numba (the fast extra) is not installed")
def test_numba_and_python_give_the_same_cells():
    found = 0
    for seed in range(20):
        cost, free = _grid(seed, 60, 70)
        cost[~free] = np.inf
        rng = np.random.default_rng(seed)
        start, goal = (int(c) for c in rng.choice(np.flatnonzero(free), 2, replace=False))
        python = astar.search(cost, free, start, goal, 70, 50.0)
        numba = astar.compiled_search(cost, free, start, goal, 70, 50.0)
        assert np.array_equal(python, numba)
        found += len(python) > 0
    assert found >= 10  # most of the pairs are joined


def test_a_walled_goal_has_no_way_and_the_start_is_its_own_way():
    cost, free = np.full(25, 50.0), np.ones(25, dtype=bool)
    free[[7, 11, 13, 17, 6, 8, 16, 18]] = False  # the ring around cell 12 of a 5 x 5 grid
    assert len(astar.search(cost, free, 0, 12, 5, 50.0)) == 0
    assert astar.search(cost, free, 0, 0, 5, 50.0).tolist() == [0]
    # open ground: the diagonal, four moves of sqrt 2 x 100
    cells = astar.search(np.full(25, 50.0), np.ones(25, dtype=bool), 0, 24, 5, 50.0)
    assert cells.tolist() == [0, 6, 12, 18, 24]


def test_the_bounds_hold_every_cell_that_costs_and_reset_empties_them():
    config = CostmapConfig(size=8.0, inscribed_radius=0.12)
    maps = LaserCostmaps(config, 2)
    n = config.cells
    assert maps.bounds(0) == (n, n, 0, 0)
    rng = np.random.default_rng(3)
    angles = np.radians(np.arange(-180.0, 180.0, 1.0))
    seen = []
    for pose in ([0.0, 0.0, 0.0], [1.5, -0.5, 1.0], [-1.0, 2.0, -2.0]):
        ranges = rng.uniform(0.2, 2.0, (1, 360)).astype(np.float32)
        maps.update([0], np.array([pose]), ranges, angles)
        x_lo, y_lo, x_hi, y_hi = maps.bounds(0)
        ys, xs = np.nonzero(maps.costs(0) != FREE)
        assert x_lo <= xs.min() and xs.max() < x_hi and y_lo <= ys.min() and ys.max() < y_hi
        seen.append((x_lo, y_lo, x_hi, y_hi))
    assert seen[0][0] >= seen[1][0] >= seen[2][0] and seen[0][3] <= seen[2][3]  # it grows
    # the first scan's returns within 2 m (40 cells) and its inflation (6): a box near that
    assert seen[0][2] - seen[0][0] <= 2 * (40 + 6) + 2
    assert maps.bounds(1) == (n, n, 0, 0)  # the other car saw nothing
    maps.reset([0])
    assert maps.bounds(0) == (n, n, 0, 0)
