"""DWA's costly part: which rollouts' footprints touch an obstacle point, and how near they pass.

``footprint_check(poses, cos, sin, points, counts, ...)`` answers, for every candidate of
every robot, whether any pose along its rollout has an obstacle point inside the padded
footprint rectangle (``valid``: none has), and the smallest distance from a pose to a point
(``nearest``; ``cutoff`` where no point is nearer: choose it beyond the inflation
radius, where the cost is 0); ``to_nearest(points, targets)`` the distance from each rollout's
end to the global path. Two ways, the same numbers bit for bit (``tests/test_dwa.py``):

* numpy: every (candidate, pose, point) at once, ``(N, C, T, P)`` arrays;
* numba (the ``fast`` extra): per pose, only the points of a fine grid's cells within the
  footprint's reach (or the nearest distance so far), and a candidate is dropped at its first
  touching pose. On a BARN world with 50 scans of memory this is about 200 times faster
  (docs/barn.md).

Both take the poses' cosines and sines from the caller (numpy's, so that both see the same
bits) and do the same float operations in the same order: no fast-math.
"""

from __future__ import annotations

import math
import os

import numpy as np

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

from smartcar_gym.parallel import run_chunks

FAR_M = 1e3  # where padding points lie (m): beyond any footprint and cutoff
GRID_DIVISIONS = 8  # the compiled check's grid cells per cutoff (measured: 2x faster than 1)
#: whether the compiled check is used (numba installed and ``SMARTCAR_GYM_NUMBA`` not ``0``)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"


def footprint_check_numpy(poses: np.ndarray, cos: np.ndarray, sin: np.ndarray,
                          points: np.ndarray, counts: np.ndarray, half_x: float,
                          half_y: float, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """``(valid, nearest)``, both ``(N, C)``, for ``poses`` ``(N, C, T, 3)`` with their
    ``cos``/``sin`` ``(N, C, T)``, obstacle ``points`` ``(N, P, 2)`` of which the first
    ``counts[n]`` are real, a footprint of half extents ``half_x``, ``half_y`` (padding in)."""
    n, c = poses.shape[:2]
    valid = np.ones((n, c), dtype=bool)
    nearest = np.full((n, c), cutoff)
    p = int(counts.max()) if n else 0
    if p == 0:
        return valid, nearest
    real = np.arange(p) < counts[:, None]  # (N, P)
    ox = np.where(real, points[:, :p, 0], FAR_M)[:, None, None, :]
    oy = np.where(real, points[:, :p, 1], FAR_M)[:, None, None, :]
    dx = ox - poses[..., 0, None]
    dy = oy - poses[..., 1, None]
    lx = cos[..., None] * dx + sin[..., None] * dy
    ly = cos[..., None] * dy - sin[..., None] * dx
    hit = (np.abs(lx) < half_x) & (np.abs(ly) < half_y)
    valid = ~np.any(hit, axis=(2, 3))
    d2 = np.min(dx * dx + dy * dy, axis=(2, 3))
    nearest = np.where(d2 < cutoff * cutoff, np.sqrt(d2), cutoff)
    return valid, nearest


def _grid(points, k, g):
    """Robot's first ``k`` points sorted into a grid of ``g``-sized cells, row by row (a row's
    cells lie together): (xs, ys, start, gx, gy, lo_x, lo_y), cell q's points
    ``start[q]:start[q + 1]`` (a counting sort)."""
    lo_x, lo_y = points[0, 0], points[0, 1]
    hi_x, hi_y = lo_x, lo_y
    for j in range(1, k):
        lo_x = min(lo_x, points[j, 0])
        lo_y = min(lo_y, points[j, 1])
        hi_x = max(hi_x, points[j, 0])
        hi_y = max(hi_y, points[j, 1])
    gx = int((hi_x - lo_x) / g) + 1
    gy = int((hi_y - lo_y) / g) + 1
    start = np.zeros(gx * gy + 1, dtype=np.int64)
    cell = np.empty(k, dtype=np.int64)
    for j in range(k):
        cell[j] = int((points[j, 1] - lo_y) / g) * gx + int((points[j, 0] - lo_x) / g)
        start[cell[j] + 1] += 1
    for q in range(gx * gy):
        start[q + 1] += start[q]
    fill = start[:-1].copy()
    xs = np.empty(k)
    ys = np.empty(k)
    for j in range(k):
        slot = fill[cell[j]]
        xs[slot] = points[j, 0]
        ys[slot] = points[j, 1]
        fill[cell[j]] += 1
    return xs, ys, start, gx, gy, lo_x, lo_y


def _candidate(way, xs, ys, start, gx, gy, lo_x, lo_y, g, half_x, half_y, cutoff):
    """One rollout ``way`` (T, 4: x, y, cos, sin of the heading) against a ``_grid``: (valid,
    nearest). Per pose only the rows and columns within ``r`` of it are read, ``r`` the
    larger of the footprint's circumscribed radius and the nearest distance found so far: a
    point beyond it can neither touch the footprint nor be nearer. Every point within ``r``
    is tested as numpy tests it; the first touching pose ends the search."""
    cut2 = cutoff * cutoff
    # the footprint lies within this of its pose (the margin: the rotated offsets' rounding)
    reach2 = (half_x * half_x + half_y * half_y) * (1.0 + 1e-9)
    best = cut2
    for s in range(way.shape[0]):
        px, py, co, si = way[s, 0], way[s, 1], way[s, 2], way[s, 3]
        r2 = max(best, reach2)
        r = math.sqrt(r2)
        # the rows and columns within r, one cell more each way (rounding)
        y0 = max(math.floor((py - r - lo_y) / g) - 1, 0)
        y1 = min(math.floor((py + r - lo_y) / g) + 1, gy - 1)
        x0 = max(math.floor((px - r - lo_x) / g) - 1, 0)
        x1 = min(math.floor((px + r - lo_x) / g) + 1, gx - 1)
        if y0 > y1 or x0 > x1:
            continue  # no point within r of this pose
        for row in range(y0, y1 + 1):
            for j in range(start[row * gx + x0], start[row * gx + x1 + 1]):
                dx = xs[j] - px
                dy = ys[j] - py
                d2 = dx * dx + dy * dy
                if d2 >= r2:
                    continue
                lx = co * dx + si * dy
                ly = co * dy - si * dx
                if abs(lx) < half_x and abs(ly) < half_y:
                    return False, cutoff
                if d2 < best:
                    best = d2
                    r2 = max(best, reach2)
    return True, (np.sqrt(best) if best < cut2 else cutoff)


def _check_loops(poses, cos, sin, points, counts, half_x, half_y, cutoff, valid, nearest):
    """The compiled check, into ``valid`` and ``nearest`` (see ``footprint_check_numpy``):
    per robot its points in a grid of ``cutoff / GRID_DIVISIONS`` cells (``_grid``), each
    candidate's way against it (``_candidate``)."""
    n, c, t = poses.shape[0], poses.shape[1], poses.shape[2]
    g = cutoff / GRID_DIVISIONS
    way = np.empty((t, 4))
    for i in range(n):
        k = counts[i]
        if k == 0:
            continue
        xs, ys, start, gx, gy, lo_x, lo_y = _grid(points[i], k, g)
        for m in range(c):
            for s in range(t):
                way[s, 0], way[s, 1] = poses[i, m, s, 0], poses[i, m, s, 1]
                way[s, 2], way[s, 3] = cos[i, m, s], sin[i, m, s]
            valid[i, m], nearest[i, m] = _candidate(way, xs, ys, start, gx, gy, lo_x, lo_y, g,
                                                    half_x, half_y, cutoff)


def _window_loops(vs, ws, cos_w, sin_w, t, fixed, points, counts, half_x, half_y, cutoff,
                  valid, nearest, end):
    """``_check_loops`` for a dynamic window's rollouts made on the fly (``window_check``),
    and each way's end point into ``end``."""
    n, nv, nw, steps = vs.shape[0], vs.shape[1], ws.shape[1], t.shape[0]
    g = cutoff / GRID_DIVISIONS
    way = np.empty((steps, 4))
    for i in range(n):
        k = counts[i]
        grid = _grid(points[i], k, g) if k > 0 else None
        for m in range(nv * nw + fixed.shape[0]):
            if m < nv * nw:  # dwa.arcs' arithmetic, pose by pose
                v, w = vs[i, m // nw], ws[i, m % nw]
                straight = abs(w) < 1e-9
                ratio = v / (1.0 if straight else w)
                for s in range(steps):
                    co, si = cos_w[i, m % nw, s], sin_w[i, m % nw, s]
                    way[s, 0] = v * t[s] if straight else ratio * si
                    way[s, 1] = 0.0 if straight else ratio * (1.0 - co)
                    way[s, 2], way[s, 3] = co, si
            else:
                way[:, :] = fixed[m - nv * nw]
            end[i, m, 0], end[i, m, 1] = way[steps - 1, 0], way[steps - 1, 1]
            if grid is not None:
                xs, ys, start, gx, gy, lo_x, lo_y = grid
                valid[i, m], nearest[i, m] = _candidate(way, xs, ys, start, gx, gy, lo_x,
                                                        lo_y, g, half_x, half_y, cutoff)


def nearest_numpy(points: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """``(N, C)``: the distance from each of ``points`` ``(N, C, 2)`` to the nearest of
    ``targets`` ``(N, Q, 2)`` (Q >= 1)."""
    d = points[:, :, None, :] - targets[:, None]
    return np.sqrt(np.min(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1], axis=-1))


def _nearest_loops(points, targets, out):
    """``nearest_numpy``, compiled, into ``out``."""
    for i in range(points.shape[0]):
        for m in range(points.shape[1]):
            best = np.inf
            for q in range(targets.shape[1]):
                dx = points[i, m, 0] - targets[i, q, 0]
                dy = points[i, m, 1] - targets[i, q, 1]
                d2 = dx * dx + dy * dy
                if d2 < best:
                    best = d2
            out[i, m] = np.sqrt(best)


if COMPILED:
    _grid = numba.njit(cache=True, nogil=True)(_grid)
    _candidate = numba.njit(cache=True, nogil=True)(_candidate)
    _compiled = numba.njit(cache=True, nogil=True)(_check_loops)
    _compiled_window = numba.njit(cache=True, nogil=True)(_window_loops)
    _compiled_nearest = numba.njit(cache=True)(_nearest_loops)


def to_nearest(points: np.ndarray, targets: np.ndarray, compiled: bool | None = None
            ) -> np.ndarray:
    """``nearest_numpy``'s answer, compiled where numba is (as ``footprint_check``)."""
    if not (COMPILED if compiled is None else compiled):
        return nearest_numpy(points, targets)
    out = np.empty(points.shape[:2])
    _compiled_nearest(np.ascontiguousarray(points, dtype=float),
                      np.ascontiguousarray(targets, dtype=float), out)
    return out


def footprint_check(poses: np.ndarray, cos: np.ndarray, sin: np.ndarray, points: np.ndarray,
                    counts: np.ndarray, half_x: float, half_y: float, cutoff: float,
                    compiled: bool | None = None, threads: int = 1
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``footprint_check_numpy``'s answer, compiled where numba is (``compiled``: None, where
    it is; False: numpy), the robots split over ``threads`` (``parallel.run_chunks``).
    ``cutoff`` must hold the footprint: at least its circumscribed radius, so that a point
    beyond it cannot touch."""
    if cutoff < float(np.hypot(half_x, half_y)):
        raise ValueError(f"cutoff {cutoff} m is inside the footprint's circumscribed radius")
    if not (COMPILED if compiled is None else compiled):
        return footprint_check_numpy(poses, cos, sin, points, counts, half_x, half_y, cutoff)
    if not COMPILED:
        raise RuntimeError("the compiled footprint check needs numba: pip install "
                           '"smartcar-gym[fast]"')
    n, c = poses.shape[:2]
    valid = np.ones((n, c), dtype=np.bool_)
    nearest = np.full((n, c), float(cutoff))
    poses, cos, sin, points = (np.ascontiguousarray(a, dtype=float)
                               for a in (poses, cos, sin, points))
    counts = np.ascontiguousarray(counts, dtype=np.int64)

    def work(a: int, b: int) -> None:
        _compiled(poses[a:b], cos[a:b], sin[a:b], points[a:b], counts[a:b], float(half_x),
                  float(half_y), float(cutoff), valid[a:b], nearest[a:b])

    run_chunks(work, n, threads)
    return valid, nearest


def window_check(vs: np.ndarray, ws: np.ndarray, cos_w: np.ndarray, sin_w: np.ndarray,
                 t: np.ndarray, fixed: np.ndarray, points: np.ndarray, counts: np.ndarray,
                 half_x: float, half_y: float, cutoff: float, threads: int = 1
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``footprint_check`` of a dynamic window's rollouts without making them first
    (compiled only): candidates ``vs`` (N, V) x ``ws`` (N, W) (``dwa.arcs``' arcs, their
    headings' cosines and sines ``cos_w``, ``sin_w`` (N, W, T) at times ``t`` (T,)), then
    ``fixed`` (F, T, 4) ways every robot has (x, y, cos, sin). ``(valid, nearest, end)``:
    (N, V W + F) twice and each way's end point (N, V W + F, 2), bit for bit what
    ``footprint_check`` and ``arcs`` give."""
    if not COMPILED:
        raise RuntimeError("window_check is compiled only: pip install "
                           '"smartcar-gym[fast]"')
    n, c = len(vs), vs.shape[1] * ws.shape[1] + len(fixed)
    valid = np.ones((n, c), dtype=np.bool_)
    nearest = np.full((n, c), float(cutoff))
    end = np.empty((n, c, 2))
    vs, ws, cos_w, sin_w, t, fixed, points = (np.ascontiguousarray(a, dtype=float) for a in (
        vs, ws, cos_w, sin_w, t, fixed, points))
    counts = np.ascontiguousarray(counts, dtype=np.int64)

    def work(a: int, b: int) -> None:
        _compiled_window(vs[a:b], ws[a:b], cos_w[a:b], sin_w[a:b], t, fixed, points[a:b],
                         counts[a:b], float(half_x), float(half_y), float(cutoff),
                         valid[a:b], nearest[a:b], end[a:b])

    run_chunks(work, n, threads)
    return valid, nearest, end
