"""The laser costmap planner's search (``costmap_planner.plan_on_costmap``): A* over a grid's
8 neighbours, one Python function (``search``) that numba compiles where the ``fast`` extra is
installed and that runs as plain Python otherwise. Both run the same code on the same floats
in the same heap order, so they return the same cells (``tests/test_costmap_planner.py``).

A move between neighbours costs its length in cells (1 or sqrt 2) times the sum of the two
cells' costs (twice navfn's mean: the same order of paths); a cell's cost is read from the
costmap through a table of 256 values, in place. The heuristic is the octile distance to the
goal times twice the least cost a cell may have (a free cell's), which never
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


def search(grid: np.ndarray, table: np.ndarray, start: int, goal: int) -> np.ndarray:
    """The cheapest 8-connected way from cell ``start`` to ``goal`` (flat indices, row by row)
    of ``grid`` (H, W; uint8 costmap costs, read in place), as the flat indices of its cells
    from start to goal; empty if there is none. A cell of cost ``c`` costs ``table[c]`` (256
    values, ``inf``: impassable), the start's ``table[0]`` whatever its own (navfn's
    ``clearRobotCell``); ``table[0]`` is the least, the heuristic's unit."""
    ny, nx = grid.shape
    size = ny * nx
    floor = table[0]
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
        here = floor if i == start else table[grid[y, x]]
        for k in range(8):
            xx, yy = x + _DX[k], y + _DY[k]
            if xx < 0 or yy < 0 or xx >= nx or yy >= ny:
                continue
            j = yy * nx + xx
            there = floor if j == start else table[grid[yy, xx]]
            if closed[j] or there == np.inf:
                continue
            step = here + there
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
