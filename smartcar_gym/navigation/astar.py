"""The laser costmap planner's search (``costmap_planner.plan_on_costmap``): A* over a grid's
8 neighbours, one Python function (``search``) that numba compiles where the ``fast`` extra is
installed and that runs as plain Python otherwise. Both run the same code on the same floats
in the same heap order, so they return the same cells (``tests/test_costmap_planner.py``).

A move between neighbours costs its length in cells (1 or sqrt 2) times the sum of the two
cells' costs (twice navfn's mean: the same order of paths). The heuristic is the octile
distance to the goal times twice the least cost a cell may have (``floor``), which never
overestimates, so the path is a cheapest one; among moves of equal estimate the deeper is
taken first (heap key ``(f, -g, cell)``), then the lower cell index, so that every tie is
broken one way.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from smartcar_gym.navigation.costmap_loops import COMPILED, numba

SQRT2 = math.sqrt(2.0)
_DX = np.array([1, -1, 0, 0, 1, 1, -1, -1], dtype=np.int64)
_DY = np.array([0, 0, 1, -1, 1, -1, 1, -1], dtype=np.int64)


def search(cost: np.ndarray, free: np.ndarray, start: int, goal: int, nx: int,
           floor: float) -> np.ndarray:
    """The cheapest 8-connected way from flat cell ``start`` to ``goal`` of a grid ``nx``
    cells wide (``cost``, ``free``: flat, row by row) through ``free`` cells, as the flat
    indices of its cells from start to goal; empty if there is none. ``floor``: the least
    value of ``cost`` (the heuristic's unit)."""
    size = cost.shape[0]
    g = np.full(size, np.inf)
    parent = np.full(size, -1, dtype=np.int64)
    closed = np.zeros(size, dtype=np.bool_)
    gx, gy = goal % nx, goal // nx
    unit = 2.0 * floor
    g[start] = 0.0
    dx0, dy0 = abs(start % nx - gx), abs(start // nx - gy)
    h0 = unit * (max(dx0, dy0) - min(dx0, dy0) + SQRT2 * min(dx0, dy0))
    heap = [(h0, -0.0, start)]
    found = False
    while len(heap) > 0:
        _, _, i = heapq.heappop(heap)
        if closed[i]:
            continue
        closed[i] = True
        if i == goal:
            found = True
            break
        x, y = i % nx, i // nx
        for k in range(8):
            xx, yy = x + _DX[k], y + _DY[k]
            if xx < 0 or yy < 0 or xx >= nx or yy * nx + xx >= size:
                continue
            j = yy * nx + xx
            if closed[j] or not free[j]:
                continue
            step = cost[i] + cost[j]
            if k >= 4:
                step = SQRT2 * step
            gj = g[i] + step
            if gj < g[j]:
                g[j] = gj
                parent[j] = i
                ddx, ddy = abs(xx - gx), abs(yy - gy)
                h = unit * (max(ddx, ddy) - min(ddx, ddy) + SQRT2 * min(ddx, ddy))
                heapq.heappush(heap, (gj + h, -gj, j))
    if not found:
        return np.zeros(0, dtype=np.int64)
    count, i = 1, goal
    while i != start:
        i = parent[i]
        count += 1
    cells = np.empty(count, dtype=np.int64)
    i = goal
    for m in range(count - 1, -1, -1):
        cells[m] = i
        i = parent[i]
    return cells


#: ``search`` compiled by numba (the ``fast`` extra); None where numba is not installed
compiled_search = None
if COMPILED:
    compiled_search = numba.njit(cache=True, nogil=True)(search)
