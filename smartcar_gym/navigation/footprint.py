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


def _check_loops(poses, cos, sin, points, counts, half_x, half_y, cutoff, valid, nearest):
    """The compiled check, into ``valid`` and ``nearest`` (see ``footprint_check_numpy``).

    Per robot its points are sorted into a grid of ``cutoff / GRID_DIVISIONS`` cells, row by
    row (a row's cells lie together). Per pose only the rows and columns within ``r`` of it
    are read, ``r`` the larger of the footprint's circumscribed radius and the nearest
    distance found so far for the candidate: a point beyond it can neither touch the
    footprint nor be nearer. Every point within ``r`` is tested as numpy tests it."""
    n, c, t = poses.shape[0], poses.shape[1], poses.shape[2]
    cut2 = cutoff * cutoff
    g = cutoff / GRID_DIVISIONS
    # the footprint within this of the pose (the margin: rounding of the rotated offsets)
    reach2 = (half_x * half_x + half_y * half_y) * (1.0 + 1e-9)
    for i in range(n):
        k = counts[i]
        if k == 0:
            continue
        lo_x, lo_y = points[i, 0, 0], points[i, 0, 1]
        hi_x, hi_y = lo_x, lo_y
        for j in range(1, k):
            lo_x = min(lo_x, points[i, j, 0])
            lo_y = min(lo_y, points[i, j, 1])
            hi_x = max(hi_x, points[i, j, 0])
            hi_y = max(hi_y, points[i, j, 1])
        gx = int((hi_x - lo_x) / g) + 1
        gy = int((hi_y - lo_y) / g) + 1
        start = np.zeros(gx * gy + 1, dtype=np.int64)  # the points sorted by cell (counting)
        cell = np.empty(k, dtype=np.int64)
        for j in range(k):
            cell[j] = int((points[i, j, 1] - lo_y) / g) * gx + int((points[i, j, 0] - lo_x) / g)
            start[cell[j] + 1] += 1
        for q in range(gx * gy):
            start[q + 1] += start[q]
        fill = start[:-1].copy()
        xs = np.empty(k)
        ys = np.empty(k)
        for j in range(k):
            slot = fill[cell[j]]
            xs[slot] = points[i, j, 0]
            ys[slot] = points[i, j, 1]
            fill[cell[j]] += 1
        for m in range(c):
            best = cut2
            ok = True
            for s in range(t):
                px, py = poses[i, m, s, 0], poses[i, m, s, 1]
                co, si = cos[i, m, s], sin[i, m, s]
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
                            ok = False
                            break
                        if d2 < best:
                            best = d2
                            r2 = max(best, reach2)
                    if not ok:
                        break
                if not ok:
                    break
            valid[i, m] = ok
            if best < cut2:
                nearest[i, m] = np.sqrt(best)


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
    _compiled = numba.njit(cache=True)(_check_loops)
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
                    compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``footprint_check_numpy``'s answer, compiled where numba is (``compiled``: None, where
    it is; False: numpy). ``cutoff`` must hold the footprint: at least its circumscribed
    radius, so that a point beyond it cannot touch."""
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
    _compiled(np.ascontiguousarray(poses, dtype=float), np.ascontiguousarray(cos, dtype=float),
              np.ascontiguousarray(sin, dtype=float), np.ascontiguousarray(points, dtype=float),
              np.ascontiguousarray(counts, dtype=np.int64), float(half_x), float(half_y),
              float(cutoff), valid, nearest)
    return valid, nearest
