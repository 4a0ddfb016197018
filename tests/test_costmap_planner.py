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
from smartcar_gym.navigation.costmap_planner import NAVFN_TABLE

MOVES = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]


def _grid(seed: int, ny: int = 40, nx: int = 50) -> np.ndarray:
    """Costmap costs: mostly free, some inflated, blobs of obstacles (253, 254)."""
    rng = np.random.default_rng(seed)
    grid = np.where(rng.random((ny, nx)) < 0.3, rng.integers(1, 253, (ny, nx)), 0)
    grid[rng.random((ny, nx)) < 0.25] = 254
    return grid.astype(np.uint8)


def _way_cost(cells: np.ndarray, cost: np.ndarray, nx: int) -> float:
    xs, ys = cells % nx, cells // nx
    steps = np.hypot(np.diff(xs), np.diff(ys))
    assert np.all((steps == 1) | (steps == math.sqrt(2)))  # neighbours, one move each
    return float(np.sum(steps * (cost[cells[:-1]] + cost[cells[1:]])))


def _dijkstra(cost: np.ndarray, nx: int, start: int) -> np.ndarray:
    """scipy's distances from ``start`` over the same graph (flat ``cost``, inf impassable)."""
    ny = len(cost) // nx
    free = np.isfinite(cost)
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
    return dijkstra(graph, indices=start)


@pytest.mark.parametrize("seed", range(6))
def test_the_search_finds_a_cheapest_way_as_dijkstra_does(seed):
    grid = _grid(seed)
    nx = 50
    rng = np.random.default_rng(100 + seed)
    start, goal = (int(c) for c in rng.choice(np.flatnonzero(grid.ravel() < 253), 2,
                                              replace=False))
    grid.ravel()[start] = 254  # the start's own cost does not count (clearRobotCell)
    cost = NAVFN_TABLE[grid.ravel()]
    cost[start] = NAVFN_TABLE[0]
    best = _dijkstra(cost, nx, start)[goal]
    cells = astar.search(grid, NAVFN_TABLE, start, goal)
    if not np.isfinite(best):
        assert len(cells) == 0
        return
    assert cells[0] == start and cells[-1] == goal and np.isfinite(cost[cells]).all()
    assert _way_cost(cells, cost, nx) == pytest.approx(best, rel=1e-12)


def test_the_navfn_table_is_50_plus_0_8_cost_and_253_up_impassable():
    assert NAVFN_TABLE[[0, 1, 100, 252]].tolist() == [50.0, 50.0, 130.0, 251.0]
    assert np.isinf(NAVFN_TABLE[253:]).all()


@pytest.mark.skipif(not COMPILED, reason="numba (the fast extra) is not installed")
def test_numba_and_python_give_the_same_cells():
    found = 0
    for seed in range(20):
        grid = _grid(seed, 60, 70)[5:55, 3:66]  # a view, as the planner passes its box
        rng = np.random.default_rng(seed)
        start, goal = (int(c) for c in rng.choice(grid.size, 2, replace=False))
        python = astar.search(grid, NAVFN_TABLE, start, goal)
        numba = astar.compiled_search(grid, NAVFN_TABLE, start, goal)
        assert np.array_equal(python, numba)
        found += len(python) > 0
    assert found >= 8  # many of the pairs are joined


def test_a_walled_goal_has_no_way_and_the_start_is_its_own_way():
    grid = np.zeros((5, 5), dtype=np.uint8)
    grid.ravel()[[7, 11, 13, 17, 6, 8, 16, 18]] = 253  # the ring around cell 12
    assert len(astar.search(grid, NAVFN_TABLE, 0, 12)) == 0
    assert astar.search(grid, NAVFN_TABLE, 0, 0).tolist() == [0]
    # open ground: the diagonal, four moves of sqrt 2 x 100
    cells = astar.search(np.zeros((5, 5), dtype=np.uint8), NAVFN_TABLE, 0, 24)
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
