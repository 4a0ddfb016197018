"""The laser costmap's cell work (``navigation/costmap.py``): an update's beams as cells
(``beams_to_cells`` in numpy; ``beams_to_cells_compiled``, numba's loops on numpy's cosines,
sines and hypot, the same float operations in the same order) and the grids' clearing,
marking and inflation from them, in numpy (``trace_cells``, ``inflate_numpy``) and in numba's
loops (``update_loops``, compiled as ``compiled_update`` where numba is installed), integer
work that gives the same arrays.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import distance_transform_edt

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

if TYPE_CHECKING:
    from smartcar_gym.navigation.costmap import CostmapConfig

#: whether the loops run compiled (numba installed, ``SMARTCAR_GYM_NUMBA`` not ``0``)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"
FREE, INSCRIBED, LETHAL = 0, 253, 254  # costmap_2d's cost_values.h


@dataclass(frozen=True)
class Beams:
    """One update's beams as cells (numpy's float work, the loops' input): per car the laser's
    cell (``x0``, ``y0``, on the grid where ``ok``) and per beam its trace (to ``x1, y1``,
    ``end`` + 1 cells where ``trace``) and its marked cell (``mx``, ``my`` where ``mark``),
    and the box of cells to inflate again (``box``: x_lo, y_lo, x_hi, y_hi, exclusive)."""

    x0: np.ndarray
    y0: np.ndarray
    ok: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    end: np.ndarray
    trace: np.ndarray
    mx: np.ndarray
    my: np.ndarray
    mark: np.ndarray
    box: np.ndarray


def beams_to_cells(config: CostmapConfig, poses: np.ndarray, ranges: np.ndarray,
           angles: np.ndarray) -> Beams:
    """The beams of scans ``ranges`` (K, B) from laser ``poses`` (K, 3) as cells, by
    ``raytraceFreespace``'s and ``updateBounds``' arithmetic (module docstring)."""
    n, res = config.cells, config.resolution
    ox0, oy0 = config.corner
    end_x, end_y = ox0 + n * res, oy0 + n * res
    r = np.asarray(ranges, dtype=np.float64)
    ox, oy = poses[:, 0:1], poses[:, 1:2]
    heading = poses[:, 2:3] + np.asarray(angles, dtype=np.float64)[None, :]
    used = (r > 0) & ~np.isnan(r) & (r != -np.inf)  # +inf stays: it clears
    reach = np.where(np.isinf(r), config.raytrace_range, np.where(used, r, 0.0))
    wx = ox + reach * np.cos(heading)
    wy = oy + reach * np.sin(heading)
    ok = (ox[:, 0] >= ox0) & (oy[:, 0] >= oy0)
    x0 = np.where(ok, (ox[:, 0] - ox0) / res, 0).astype(np.int64)
    y0 = np.where(ok, (oy[:, 0] - oy0) / res, 0).astype(np.int64)
    ok &= (x0 < n) & (y0 < n)
    # marking: returns within obstacle_range whose cell is on the grid
    mark = used & np.isfinite(r) & (r < config.obstacle_range) & (wx >= ox0) & (wy >= oy0)
    mx = np.where(mark, (wx - ox0) / res, 0).astype(np.int64)
    my = np.where(mark, (wy - oy0) / res, 0).astype(np.int64)
    mark &= (mx < n) & (my < n)
    # clearing: the end point pulled onto the grid, in raytraceFreespace's order
    a, b = wx - ox, wy - oy
    with np.errstate(divide="ignore", invalid="ignore"):
        low = wx < ox0
        wy = np.where(low, oy + b * ((ox0 - ox) / a), wy)
        wx = np.where(low, ox0, wx)
        low = wy < oy0
        wx = np.where(low, ox + a * ((oy0 - oy) / b), wx)
        wy = np.where(low, oy0, wy)
        high = wx > end_x
        wy = np.where(high, oy + b * ((end_x - ox) / a), wy)
        wx = np.where(high, end_x - 0.001, wx)
        high = wy > end_y
        wx = np.where(high, ox + a * ((end_y - oy) / b), wx)
        wy = np.where(high, end_y - 0.001, wy)
    trace = used & ok[:, None] & (wx >= ox0) & (wy >= oy0)
    x1 = np.where(trace, (wx - ox0) / res, 0).astype(np.int64)
    y1 = np.where(trace, (wy - oy0) / res, 0).astype(np.int64)
    trace &= (x1 < n) & (y1 < n)
    x1, y1 = np.where(trace, x1, x0[:, None]), np.where(trace, y1, y0[:, None])
    # raytraceLine's cut: (unsigned)(scale * major), scale = min(1, max_length / hypot)
    dx, dy = x1 - x0[:, None], y1 - y0[:, None]
    major = np.maximum(np.abs(dx), np.abs(dy))
    dist = np.hypot(dx, dy)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(dist == 0.0, 1.0, np.minimum(1.0, config.raytrace_cells / dist))
    end = np.minimum((scale * major).astype(np.int64), major)
    # the box of touched cells: each trace's last cell (Bresenham's, closed form), the marks
    sx, sy = np.where(dx > 0, 1, -1), np.where(dy > 0, 1, -1)
    minor = np.minimum(np.abs(dx), np.abs(dy))
    steps = np.where(major > 0, (major // 2 + end * minor) // np.maximum(major, 1), 0)
    x_dom = np.abs(dx) >= np.abs(dy)
    lx = x0[:, None] + sx * np.where(x_dom, end, steps)
    ly = y0[:, None] + sy * np.where(x_dom, steps, end)
    big = np.iinfo(np.int64).max
    box = np.empty((len(poses), 4), dtype=np.int64)
    grow = config.inflation_cells
    for i, (last, marked, origin) in enumerate(((lx, mx, x0), (ly, my, y0))):
        lo = np.minimum(np.where(trace, last, big).min(axis=1, initial=big),
                        np.where(mark, marked, big).min(axis=1, initial=big))
        hi = np.maximum(np.where(trace, last, -1).max(axis=1, initial=-1),
                        np.where(mark, marked, -1).max(axis=1, initial=-1))
        lo = np.where(ok, np.minimum(lo, origin), lo)
        hi = np.where(ok, np.maximum(hi, origin), hi)
        box[:, i] = np.clip(lo - grow, 0, n)
        box[:, i + 2] = np.where(hi >= 0, np.clip(hi + grow + 1, 0, n), 0)
    return Beams(x0, y0, ok, x1, y1, end, trace, mx, my, mark, box)


def beams_to_cells_compiled(config: CostmapConfig, poses: np.ndarray, ranges: np.ndarray,
                            angles: np.ndarray) -> Beams:
    """``beams_to_cells``' arrays, bit for bit, from two compiled passes (about five times
    faster; split over two threads they were slower still): the beams' headings, cosines and
    sines are numpy's (the same bits as ``beams_to_cells``' own), and so are the traces'
    lengths (``np.hypot``); the rest the same float operations in the same order."""
    k, b = np.asarray(ranges).shape
    r = np.ascontiguousarray(ranges, dtype=np.float64)
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    heading = poses[:, 2:3] + np.asarray(angles, dtype=np.float64)[None, :]
    cos, sin = np.cos(heading), np.sin(heading)
    x1, y1, end, mx, my = (np.empty((k, b), dtype=np.int64) for _ in range(5))
    trace, mark = np.empty((k, b), dtype=np.bool_), np.empty((k, b), dtype=np.bool_)
    x0, y0 = np.empty(k, dtype=np.int64), np.empty(k, dtype=np.int64)
    ok, box = np.empty(k, dtype=np.bool_), np.empty((k, 4), dtype=np.int64)
    ox0, oy0 = config.corner
    grid = np.array([config.cells, config.raytrace_cells, config.inflation_cells],
                    dtype=np.int64)
    lengths = np.array([ox0, oy0, config.resolution, config.raytrace_range,
                        config.obstacle_range])
    compiled_beams(poses, r, cos, sin, grid, lengths, x0, y0, ok, x1, y1, trace, mx, my, mark)
    # numpy's hypot, as beams_to_cells' (numba's is another function, and slower)
    dist = np.hypot(x1 - x0[:, None], y1 - y0[:, None])
    compiled_cut(x0, y0, ok, x1, y1, dist, trace, mx, my, mark, grid, end, box)
    return Beams(x0, y0, ok, x1, y1, end, trace, mx, my, mark, box)


def beams_loops(poses, ranges, cos, sin, grid, lengths, x0, y0, ok, x1, y1, trace, mx, my,
                mark):
    """``beams_to_cells`` car by car and beam by beam up to the traces' cut
    (``beams_to_cells_compiled``): ``grid`` (cells, raytrace cells, inflation cells),
    ``lengths`` (the corner's x and y, resolution, raytrace and obstacle ranges)."""
    n = grid[0]
    ox0, oy0, res, ray_range, obstacle_range = (lengths[0], lengths[1], lengths[2],
                                                lengths[3], lengths[4])
    end_x, end_y = ox0 + n * res, oy0 + n * res
    for k in range(poses.shape[0]):
        ox, oy = poses[k, 0], poses[k, 1]
        okk = (ox >= ox0) and (oy >= oy0)
        cx0 = np.int64((ox - ox0) / res) if okk else np.int64(0)
        cy0 = np.int64((oy - oy0) / res) if okk else np.int64(0)
        okk = okk and cx0 < n and cy0 < n
        x0[k], y0[k], ok[k] = cx0, cy0, okk
        for j in range(ranges.shape[1]):
            r = ranges[k, j]
            used = r > 0 and not np.isnan(r) and r != -np.inf
            reach = ray_range if np.isinf(r) else (r if used else 0.0)
            wx = ox + reach * cos[k, j]
            wy = oy + reach * sin[k, j]
            m = used and np.isfinite(r) and r < obstacle_range and wx >= ox0 and wy >= oy0
            cmx = np.int64((wx - ox0) / res) if m else np.int64(0)
            cmy = np.int64((wy - oy0) / res) if m else np.int64(0)
            m = m and cmx < n and cmy < n
            mx[k, j], my[k, j], mark[k, j] = cmx, cmy, m
            a, b_ = wx - ox, wy - oy
            if wx < ox0:
                wy = oy + b_ * ((ox0 - ox) / a)
                wx = ox0
            if wy < oy0:
                wx = ox + a * ((oy0 - oy) / b_)
                wy = oy0
            if wx > end_x:
                wy = oy + b_ * ((end_x - ox) / a)
                wx = end_x - 0.001
            if wy > end_y:
                wx = ox + a * ((end_y - oy) / b_)
                wy = end_y - 0.001
            t = used and okk and wx >= ox0 and wy >= oy0
            cx1 = np.int64((wx - ox0) / res) if t else np.int64(0)
            cy1 = np.int64((wy - oy0) / res) if t else np.int64(0)
            t = t and cx1 < n and cy1 < n
            if not t:
                cx1, cy1 = cx0, cy0
            x1[k, j], y1[k, j], trace[k, j] = cx1, cy1, t


def cut_loops(x0, y0, ok, x1, y1, dist, trace, mx, my, mark, grid, end, box):
    """The traces' cut (``raytraceLine``'s, from their lengths ``dist`` in cells) and each
    car's box to inflate again, as ``beams_to_cells`` (``beams_to_cells_compiled``)."""
    n, ray_cells, grow = grid[0], grid[1], grid[2]
    big = np.iinfo(np.int64).max
    for k in range(x1.shape[0]):
        cx0, cy0 = x0[k], y0[k]
        lo_x, lo_y, hi_x, hi_y = big, big, -1, -1
        for j in range(x1.shape[1]):
            dx, dy = x1[k, j] - cx0, y1[k, j] - cy0
            adx, ady = abs(dx), abs(dy)
            major, minor = max(adx, ady), min(adx, ady)
            d = dist[k, j]
            scale = 1.0 if d == 0.0 else min(1.0, ray_cells / d)
            e = min(np.int64(scale * major), major)
            end[k, j] = e
            if trace[k, j]:
                steps = (major // 2 + e * minor) // max(major, 1) if major > 0 else 0
                sx = 1 if dx > 0 else -1
                sy = 1 if dy > 0 else -1
                lx = cx0 + sx * (e if adx >= ady else steps)
                ly = cy0 + sy * (steps if adx >= ady else e)
                lo_x, hi_x = min(lo_x, lx), max(hi_x, lx)
                lo_y, hi_y = min(lo_y, ly), max(hi_y, ly)
            if mark[k, j]:
                lo_x, hi_x = min(lo_x, mx[k, j]), max(hi_x, mx[k, j])
                lo_y, hi_y = min(lo_y, my[k, j]), max(hi_y, my[k, j])
        if ok[k]:
            lo_x, hi_x = min(lo_x, cx0), max(hi_x, cx0)
            lo_y, hi_y = min(lo_y, cy0), max(hi_y, cy0)
        box[k, 0] = min(max(lo_x - grow, 0), n)
        box[k, 1] = min(max(lo_y - grow, 0), n)
        box[k, 2] = min(max(hi_x + grow + 1, 0), n) if hi_x >= 0 else 0
        box[k, 3] = min(max(hi_y + grow + 1, 0), n) if hi_y >= 0 else 0


def trace_cells(beams: Beams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every traced cell of every beam, as (car row k, x, y) arrays: Bresenham's cells in
    closed form (the minor axis after i steps: ``(major // 2 + i * minor) // major``)."""
    k, b = np.nonzero(beams.trace)
    x0, y0 = beams.x0[k], beams.y0[k]
    dx, dy = beams.x1[k, b] - x0, beams.y1[k, b] - y0
    end = beams.end[k, b]
    major = np.maximum(np.abs(dx), np.abs(dy))
    minor = np.minimum(np.abs(dx), np.abs(dy))
    i = np.arange(int(end.max(initial=0)) + 1)[None, :]
    keep = i <= end[:, None]
    steps = (major[:, None] // 2 + i * minor[:, None]) // np.maximum(major, 1)[:, None]
    x_dom = (np.abs(dx) >= np.abs(dy))[:, None]
    sx, sy = np.where(dx > 0, 1, -1)[:, None], np.where(dy > 0, 1, -1)[:, None]
    xs = x0[:, None] + sx * np.where(x_dom, i, steps)
    ys = y0[:, None] + sy * np.where(x_dom, steps, i)
    rows = np.broadcast_to(k[:, None], keep.shape)
    return rows[keep], xs[keep], ys[keep]


def inflate_numpy(marks: np.ndarray, costs: np.ndarray, box: np.ndarray, r: int,
                   table: np.ndarray) -> None:
    """One grid's costs in ``box`` (x_lo, y_lo, x_hi, y_hi) from its lethal ``marks``: per
    cell ``table`` at its squared distance to the nearest lethal cell (scipy's exact
    Euclidean distance transform over the box grown by ``r``), 0 beyond ``r``."""
    x_lo, y_lo, x_hi, y_hi = (int(v) for v in box)
    if x_lo >= x_hi or y_lo >= y_hi:
        return
    ny, nx = marks.shape
    h, w = y_hi - y_lo, x_hi - x_lo
    lethal = np.zeros((h + 2 * r, w + 2 * r), dtype=bool)
    sy0, sy1, sx0, sx1 = max(y_lo - r, 0), min(y_hi + r, ny), max(x_lo - r, 0), min(x_hi + r, nx)
    lethal[sy0 - y_lo + r:sy1 - y_lo + r, sx0 - x_lo + r:sx1 - x_lo + r] = (
        marks[sy0:sy1, sx0:sx1] == LETHAL)
    if not lethal.any():
        costs[y_lo:y_hi, x_lo:x_hi] = FREE
        return
    d = distance_transform_edt(~lethal)[r:r + h, r:r + w]
    d2 = np.rint(d * d).astype(np.int64)  # whole: squares of whole cell offsets
    near = d2 <= r * r
    costs[y_lo:y_hi, x_lo:x_hi] = np.where(near, table[np.where(near, d2, 0)], FREE)


def update_loops(cars, x0, y0, ok, x1, y1, end, trace, mx, my, mark, r, half, table,
                 marks, costs):
    """The compiled update of grids ``cars`` (numpy's, cell for cell): per car its beams'
    Bresenham lines cleared (``Costmap2D::bresenham2D``, step by step), then its returns
    marked, then the costs inflated again where they can have changed: within ``r`` cells of
    a cell whose mark changed (the box of those cells grown by ``r``). There each cell's cost
    is the most of ``table[dx * dx + dy * dy]`` over the lethal cells at offsets ``(dx, dy)``
    with ``|dx| <= half[|dy|]`` (the kernel of ``CostmapConfig.kernel``, rows clipped to the
    box). Elsewhere the costs, the whole grid's inflation before, still are.

    A row's lethal cells are stamped a cluster at a time (cells each within ``2r + 1`` columns
    of the last: no other lethal cell of the row is within ``r`` of the cluster's reach). A
    cell ``dy`` rows off and ``dx`` columns from the cluster's nearest lethal cell (``near``)
    gets ``table[dx * dx + dy * dy]``: the most of the cluster's cells' own stamps because
    ``table`` never rises with the distance (``CostmapConfig.cost_table``). So a cluster costs
    its kernel's rows once, not once per cell, and the rows ``dy`` above and below it share
    their costs (on updates replayed from BARN runs with the laser's noise: 1.55 ms instead of
    a run at a time's 2.2, and 3.6 a cell at a time, with the mapless policy's costmap)."""
    ny, nx = marks.shape[1], marks.shape[2]
    near = np.empty(nx, dtype=np.int64)
    for k in range(cars.shape[0]):
        g = cars[k]
        # the box of the cells whose mark changed (x_lo, y_lo, x_hi, y_hi, inclusive)
        c_x_lo, c_y_lo, c_x_hi, c_y_hi = nx, ny, -1, -1
        if ok[k]:
            for b in range(x1.shape[1]):
                if not trace[k, b]:
                    continue
                dx, dy = x1[k, b] - x0[k], y1[k, b] - y0[k]
                sx = 1 if dx > 0 else -1
                sy = 1 if dy > 0 else -1
                adx, ady = abs(dx), abs(dy)
                x, y = x0[k], y0[k]
                major, minor, error = (adx, ady, adx // 2) if adx >= ady else (ady, adx, ady // 2)
                for i in range(end[k, b] + 1):
                    if marks[g, y, x] == 254:
                        marks[g, y, x] = 0
                        c_x_lo, c_x_hi = min(c_x_lo, x), max(c_x_hi, x)
                        c_y_lo, c_y_hi = min(c_y_lo, y), max(c_y_hi, y)
                    if i == end[k, b]:
                        break
                    error += minor
                    if adx >= ady:
                        x += sx
                        if error >= major:
                            y += sy
                            error -= major
                    else:
                        y += sy
                        if error >= major:
                            x += sx
                            error -= major
        for b in range(mx.shape[1]):
            if mark[k, b]:
                x, y = mx[k, b], my[k, b]
                if marks[g, y, x] != 254:
                    marks[g, y, x] = 254
                    c_x_lo, c_x_hi = min(c_x_lo, x), max(c_x_hi, x)
                    c_y_lo, c_y_hi = min(c_y_lo, y), max(c_y_hi, y)
        if c_x_hi < 0:  # no mark changed: nor did any cost
            continue
        x_lo, y_lo = max(c_x_lo - r, 0), max(c_y_lo - r, 0)
        x_hi, y_hi = min(c_x_hi + r + 1, nx), min(c_y_hi + r + 1, ny)
        for y in range(y_lo, y_hi):
            for x in range(x_lo, x_hi):
                costs[g, y, x] = 0
        x_end = min(x_hi + r, nx)
        for sy_ in range(max(y_lo - r, 0), min(y_hi + r, ny)):
            sx_ = max(x_lo - r, 0)
            while sx_ < x_end:
                if marks[g, sy_, sx_] != 254:
                    sx_ += 1
                    continue
                first = last = sx_  # a cluster: lethal cells each within 2r + 1 of the last
                sx_ += 1
                while sx_ < x_end and sx_ <= last + 2 * r + 1:
                    if marks[g, sy_, sx_] == 254:
                        last = sx_
                    sx_ += 1
                lo, hi = max(first - r, x_lo), min(last + r + 1, x_hi)
                if lo >= hi:
                    continue
                # near[x]: the columns from x to the cluster's nearest lethal cell
                seen = -(r + 2)
                for x in range(min(first, lo), hi):
                    if x <= last and marks[g, sy_, x] == 254:
                        seen = x
                    if x >= lo:
                        near[x] = x - seen
                seen = nx + r + 2
                for x in range(max(last, hi - 1), lo - 1, -1):
                    if x >= first and marks[g, sy_, x] == 254:
                        seen = x
                    if x < hi and seen - x < near[x]:
                        near[x] = seen - x
                for d in range(r + 1):  # the rows d above and below: the same costs
                    up, down = sy_ - d, sy_ + d
                    up_ok = y_lo <= up < y_hi
                    down_ok = d > 0 and y_lo <= down < y_hi
                    if not (up_ok or down_ok):
                        continue
                    w = half[d]
                    d2 = d * d
                    for x in range(max(first - w, lo), min(last + w + 1, hi)):
                        e = near[x]
                        if e <= w:
                            c = table[e * e + d2]
                            if up_ok and c > costs[g, up, x]:
                                costs[g, up, x] = c
                            if down_ok and c > costs[g, down, x]:
                                costs[g, down, x] = c

compiled_update = compiled_beams = compiled_cut = None
if COMPILED:
    compiled_update = numba.njit(cache=True, nogil=True)(update_loops)
    # numpy's error model: a beam along the grid's edge divides by zero, as numpy's does
    compiled_beams = numba.njit(cache=True, nogil=True, error_model="numpy")(beams_loops)
    compiled_cut = numba.njit(cache=True, nogil=True, error_model="numpy")(cut_loops)
