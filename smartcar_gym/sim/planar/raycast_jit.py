"""``raycast.cast`` compiled with numba (the ``fast`` extra): the same distances and shapes bit
for bit, about ten times faster on a BARN world's laser.

The numpy cast tests every (car, shape, beam) triple whose beam points into the shape's
bounding cone, found by one matrix product per block of cars. The loops here find the same
beams by angle instead: each car's beams sorted by their direction's angle once, then per
shape the beams whose angle lies in its cone (two binary searches). The window is wider than
numpy's cone by 1e-6 rad, so it holds every beam numpy tests; a beam it holds that numpy does
not misses the shape's bounding circle by more than numpy's own margin (1e-9 of the radius),
so its exact test answers "no hit" either way. The exact tests are ``raycast._exact_hits``'
float operations in the same order (``raycast._pair_table``'s per shape), no fast-math, and
the nearest hit wins with ties to the lower shape index, as ``np.minimum.at`` gives them
(``tests/test_planar_geometry.py`` compares both on random worlds).
"""

from __future__ import annotations

import math
import os

import numpy as np

from smartcar_gym.parallel import run_chunks

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

#: whether ``cast`` uses the loops (numba installed and ``SMARTCAR_GYM_NUMBA`` not ``0``)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"

_TINY = 1e-300  # raycast._TINY
_WINDOW_MARGIN = 1e-6  # rad added to each side of a shape's cone
_CIRCLE = 1  # shapes.CIRCLE


def _fmin(a: float, b: float) -> float:
    """``np.minimum`` of two floats (NaN wins)."""
    if a != a or b != b:
        return math.nan
    return a if a < b else b


def _fmax(a: float, b: float) -> float:
    """``np.maximum`` of two floats (NaN wins)."""
    if a != a or b != b:
        return math.nan
    return a if a > b else b


def _cast_loops(origins, beams, reach, kind, centre, rotation, half, valid, radius,
                distance, hit_shape):
    """Into ``distance`` (N, B, preset to the reach) and ``hit_shape`` (N, B, preset to M):
    each ray's nearest hit. ``beams`` (1 or N, 2, B) unit vectors, ``reach`` (N, B),
    ``radius`` (N, M) the shapes' bounding radii (``Shapes2D.bounding_radius``)."""
    n, m = kind.shape
    b = beams.shape[2]
    shared = beams.shape[0] == 1
    order = np.empty(b, dtype=np.int64)
    sorted_angle = np.empty(b)
    for i in range(n):
        row = 0 if shared else i
        if i == 0 or not shared:
            angle = np.empty(b)
            for k in range(b):
                angle[k] = math.atan2(beams[row, 1, k], beams[row, 0, k])
            order[:] = np.argsort(angle, kind="mergesort")
            for k in range(b):
                sorted_angle[k] = angle[order[k]]
        longest = 0.0
        for k in range(b):
            longest = max(longest, reach[i, k])
        ox, oy = origins[i, 0], origins[i, 1]
        for j in range(m):
            if not valid[i, j]:
                continue
            wx = centre[i, j, 0] - ox
            wy = centre[i, j, 1] - oy
            c, s = rotation[i, j, 0], rotation[i, j, 1]
            hx, hy = half[i, j, 0], half[i, j, 1]
            px, py = -(c * wx + s * wy), s * wx - c * wy
            circle = kind[i, j] == _CIRCLE
            if circle:
                if px * px + py * py < hx * hx:
                    continue  # the origin inside: Bullet's rule
            elif abs(px) < hx and abs(py) < hy:
                continue
            bound = radius[i, j] * (1.0 + 1e-9) + 1e-12
            d = math.hypot(wx, wy)
            if d - bound > longest:
                continue
            # the beams whose angle lies within the shape's cone (all: the origin near it)
            lo_a, hi_a, wraps = -4.0, 4.0, False
            if bound < d * 0.999999:
                half_angle = math.asin(bound / d) + _WINDOW_MARGIN
                mid = math.atan2(wy, wx)
                lo_a, hi_a, wraps = mid - half_angle, mid + half_angle, True
            x0, x1, y0, y1, r2 = -hx - px, hx - px, -hy - py, hy - py, hx * hx
            for part in range(3):  # the window, and its wrap past -pi or past pi
                if part == 0:
                    a0, a1 = lo_a, hi_a
                elif part == 1:
                    if not wraps or lo_a >= -math.pi:
                        continue
                    a0, a1 = lo_a + 2.0 * math.pi, 4.0
                else:
                    if not wraps or hi_a <= math.pi:
                        continue
                    a0, a1 = -4.0, hi_a - 2.0 * math.pi
                start = np.searchsorted(sorted_angle, a0)
                stop = np.searchsorted(sorted_angle, a1, side="right")
                for q in range(start, stop):
                    k = order[q]
                    ux, uy = beams[row, 0, k], beams[row, 1, k]
                    if circle:
                        across = ux * wy - uy * wx
                        disc = r2 - across * across
                        first = ux * wx + uy * wy - math.sqrt(_fmax(disc, 0.0))
                        t = first if (disc >= 0.0 and first >= 0.0) else math.inf
                    else:
                        dx = c * ux + s * uy
                        dy = c * uy - s * ux
                        ix = 1.0 / (_TINY if dx == 0.0 else dx)
                        iy = 1.0 / (_TINY if dy == 0.0 else dy)
                        t1, t2, t3, t4 = x0 * ix, x1 * ix, y0 * iy, y1 * iy
                        enter = _fmax(_fmin(t1, t2), _fmin(t3, t4))
                        leave = _fmin(_fmax(t1, t2), _fmax(t3, t4))
                        t = enter if (enter <= leave and enter >= 0.0) else math.inf
                    if not t <= reach[i, k]:
                        continue
                    if t < distance[i, k]:
                        distance[i, k] = t
                        hit_shape[i, k] = j
                    elif t == distance[i, k] and j < hit_shape[i, k]:
                        hit_shape[i, k] = j


if COMPILED:
    _fmin = numba.njit(cache=True)(_fmin)
    _fmax = numba.njit(cache=True)(_fmax)
    _compiled = numba.njit(cache=True, nogil=True)(_cast_loops)


def cast_loops(origins: np.ndarray, beams: np.ndarray, reach: np.ndarray, shapes: object,
               distance: np.ndarray, hit_shape: np.ndarray, threads: int = 1) -> None:
    """Run the compiled loops (``raycast.cast`` checks the arguments and calls this), the
    cars split over ``threads`` (``parallel.run_chunks``)."""
    origins = np.ascontiguousarray(origins, dtype=float)
    beams = np.ascontiguousarray(beams)
    reach = np.ascontiguousarray(reach, dtype=float)
    kind, centre, rotation, half, valid, radius = (
        np.ascontiguousarray(a) for a in (shapes.kind, shapes.centre, shapes.rotation,
                                          shapes.half, shapes.valid, shapes.bounding_radius()))
    shared = beams.shape[0] == 1

    def work(a: int, b: int) -> None:
        _compiled(origins[a:b], beams if shared else beams[a:b], reach[a:b], kind[a:b],
                  centre[a:b], rotation[a:b], half[a:b], valid[a:b], radius[a:b],
                  distance[a:b], hit_shape[a:b])

    run_chunks(work, len(origins), threads)
