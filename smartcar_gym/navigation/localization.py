"""Localization on a known map of cylinders: the map -> odom correction from each laser scan.

On a known map a ROS robot runs amcl beside move_base: odometry drifts, and amcl publishes the
``map -> odom`` transform that puts the robot back where its scans say it is on the map; the
global plan (map frame) reaches the local planner through it. ``ScanMatcher`` is that
transform's estimate for a map of circles (the BARN worlds' cylinders): each scan's hits are
placed on the map through the current correction and the odometry pose, each is paired with
the nearest cylinder's outline, and a few Gauss-Newton steps move the correction to bring the
hits onto the outlines (the residual is a hit's distance from the circle, ``|p - c| - r``).
A hit further than ``gate_m`` from the nearest outline is left out; with fewer than
``min_hits`` hits paired the correction stays as it is. No ground truth is read.

Two ways, the same numbers bit for bit (``tests/test_barn_localization.py``): numpy, and numba
under the ``fast`` extra (one scan in about 10 us, where numpy takes about 0.2 ms). Both find a
hit's outline among the cylinders listed for its cell of a fine grid (every cylinder whose
outline can be within the gate of the cell), sum the normal equations in the hits' order
(numpy's ``cumsum``, not a pairwise sum or BLAS) and solve them with the same scalar Cholesky,
so the answer does not depend on the machine's BLAS either.

Poses and corrections are (x, y, yaw) tuples of floats; ``compose(a, b)`` is the pose ``b``
seen from the frame ``a`` (``map_pose = compose(correction, odom_pose)``), computed with
``math`` so that one car and a batch of them (one call per car) get the same bits.
"""

from __future__ import annotations

import math
import os

import numpy as np

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

Pose = tuple[float, float, float]
IDENTITY: Pose = (0.0, 0.0, 0.0)
GATE_M = 0.02  # a hit this far from every outline is not a cylinder's (m)
MIN_HITS = 20  # fewer hits on the map than this: no correction from the scan
STEPS = 2  # Gauss-Newton steps per scan (the correction changes little between scans)
MAX_BEAMS = 360  # evenly spaced beams of a scan used (amcl's laser_max_beams)
CELL_M = 0.05  # the candidate grid's cell (m)
DAMPING = 1e-9  # added to the normal matrix's diagonal
#: whether the matcher runs compiled (numba installed and ``SMARTCAR_GYM_NUMBA`` not ``0``)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"


def compose(a: Pose, b: Pose) -> Pose:
    """The pose ``b`` (in frame ``a``) in the frame ``a`` is given in."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def beam_geometry(angles: np.ndarray, mount: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The laser's origin (2,) and its beams' unit directions (B, 2) in base_link's plane, for
    beams at ``angles`` (rad, laser frame) of a laser at ``mount`` (base_link -> laser, 4x4)."""
    mount = np.asarray(mount, dtype=float)
    local = np.stack([np.cos(angles), np.sin(angles), np.zeros(len(angles))], axis=1)
    directions = (local @ mount[:3, :3].T)[:, :2]
    return mount[:2, 3].copy(), directions


def solve_step(sums: tuple, at: tuple, correction: tuple) -> tuple:
    """The correction after one Gauss-Newton step from the normal equations' ``sums`` (JtJ's
    xx, xy, xt, yy, yt, tt, then Jte's x, y, t: the residuals' normals ``n`` and lever arms
    ``m = n1 (px - at_x) - n0 (py - at_y)``), the turn taken about ``at``, the car on the
    map; ``(ok, x, y, yaw)``, ``ok`` False where the normal matrix is not positive definite.
    Plain floats, so that numba compiles the very same arithmetic (``solve_step_compiled``;
    ``scan_map`` solves its point-to-line steps with it too)."""
    a00, a01, a02, a11, a12, a22, b0, b1, b2 = sums
    a00, a11, a22 = a00 + DAMPING, a11 + DAMPING, a22 + DAMPING
    # Cholesky, A = L L^T, then L y = -b and L^T x = y
    if not a00 > 0.0:
        return False, correction[0], correction[1], correction[2]
    l00 = math.sqrt(a00)
    l10, l20 = a01 / l00, a02 / l00
    p11 = a11 - l10 * l10
    if not p11 > 0.0:
        return False, correction[0], correction[1], correction[2]
    l11 = math.sqrt(p11)
    l21 = (a12 - l20 * l10) / l11
    p22 = a22 - l20 * l20 - l21 * l21
    if not p22 > 0.0:
        return False, correction[0], correction[1], correction[2]
    l22 = math.sqrt(p22)
    y0 = -b0 / l00
    y1 = (-b1 - l10 * y0) / l11
    y2 = (-b2 - l20 * y0 - l21 * y1) / l22
    dyaw = y2 / l22
    dy = (y1 - l21 * dyaw) / l11
    dx = (y0 - l10 * dy - l20 * dyaw) / l00
    # the step turns the map about ``at`` by dyaw and moves it by (dx, dy)
    c, s = math.cos(dyaw), math.sin(dyaw)
    tx = at[0] + dx - (c * at[0] - s * at[1])
    ty = at[1] + dy - (s * at[0] + c * at[1])
    return (True, tx + c * correction[0] - s * correction[1],
            ty + s * correction[0] + c * correction[1], dyaw + correction[2])


def place_returns(odom: tuple, ranges: np.ndarray, origin: np.ndarray,
                  directions: np.ndarray, stride: int, ox: np.ndarray, oy: np.ndarray) -> int:
    """The returns (finite ranges) of every ``stride``-th beam of a scan taken at ``odom``,
    in the odom frame, written to ``ox``, ``oy`` in the beams' order: their count. For
    compiled loops (``place_returns_compiled``)."""
    c, s = math.cos(odom[2]), math.sin(odom[2])
    n = 0
    for k in range(0, ranges.shape[0], stride):
        r = ranges[k]
        if math.isfinite(r):
            bx = origin[0] + r * directions[k, 0]
            by = origin[1] + r * directions[k, 1]
            ox[n] = odom[0] + c * bx - s * by
            oy[n] = odom[1] + s * bx + c * by
            n += 1
    return n


def add_residual(sums: np.ndarray, first: bool, n0: float, n1: float, m: float,
                 e: float) -> None:
    """One residual ``e`` (normal ``n0, n1``, lever arm ``m``) added to the normal equations'
    ``sums`` (9,: ``solve_step``'s order) in place; ``first``: the sums start from it. For
    compiled loops (``add_residual_compiled``): in the residuals' order, as numpy's cumsum."""
    terms = (n0 * n0, n0 * n1, n0 * m, n1 * n1, n1 * m, m * m, n0 * e, n1 * e, m * e)
    for t in range(9):
        sums[t] = terms[t] if first else sums[t] + terms[t]


def solve_sums(sums: np.ndarray, at: tuple, correction: tuple) -> tuple:
    """``solve_step`` of the sums ``add_residual`` made (compiled: ``solve_sums_compiled``)."""
    return solve_step_compiled((sums[0], sums[1], sums[2], sums[3], sums[4], sums[5], sums[6],
                                sums[7], sums[8]), at, correction)


class ScanMatcher:
    """The map -> odom correction on a map of circles (``centres`` (M, 2), ``radii`` (M,), m).

    ``correct(correction, odom_pose, ranges, origin, directions)`` is the correction after one
    scan (``ranges`` (B,), REP 117: non-finite ranges hit nothing) taken at ``odom_pose``.
    ``compiled``: None, numba where it is installed; False, numpy; True, numba or an error.
    """

    def __init__(self, centres: np.ndarray, radii: np.ndarray, gate_m: float = GATE_M,
                 min_hits: int = MIN_HITS, steps: int = STEPS, max_beams: int = MAX_BEAMS,
                 compiled: bool | None = None) -> None:
        self.centres = np.ascontiguousarray(centres, dtype=float).reshape(-1, 2)
        self.radii = np.ascontiguousarray(
            np.broadcast_to(np.asarray(radii, dtype=float), (len(self.centres),)))
        if len(self.centres) == 0:
            raise ValueError("a map with no cylinders gives no correction")
        if not np.all(np.isfinite(self.centres)) or not np.all(self.radii > 0.0):
            raise ValueError("the map's centres must be finite and its radii positive")
        self.gate_m, self.min_hits, self.steps = float(gate_m), int(min_hits), int(steps)
        if int(max_beams) < 1:
            raise ValueError(f"max_beams must be at least 1, got {max_beams!r}")
        self.max_beams = int(max_beams)
        self.compiled = COMPILED if compiled is None else bool(compiled)
        if self.compiled and not COMPILED:
            raise RuntimeError('the compiled scan matcher needs numba: pip install '
                               '"smartcar-gym[fast]"')
        self._grid()

    def _grid(self) -> None:
        """Cells of ``CELL_M`` over the map; each lists (ascending, -1 padded) the cylinders
        whose outline can be within the gate of a point in it: its centre nearer the cell's
        than radius + gate + half the cell's diagonal. The last row, all -1, is off the map."""
        reach = self.radii + self.gate_m + CELL_M
        low = (self.centres - reach[:, None]).min(axis=0)
        high = (self.centres + reach[:, None]).max(axis=0)
        shape = np.ceil((high - low) / CELL_M).astype(int) + 1
        limit = self.radii + self.gate_m + CELL_M * math.sqrt(0.5) + 1e-6  # (M,)
        k = int(np.ceil(limit.max() / CELL_M)) + 1  # the cells that can list a cylinder
        step = np.arange(-k, k + 1)
        home = np.floor((self.centres - low) / CELL_M).astype(int)  # (M, 2)
        cx = home[:, 0, None, None] + step[None, :, None]  # (M, S, 1)
        cy = home[:, 1, None, None] + step[None, None, :]  # (M, 1, S)
        cx, cy = np.broadcast_arrays(cx, cy)
        apart = np.hypot(low[0] + (cx + 0.5) * CELL_M - self.centres[:, 0, None, None],
                         low[1] + (cy + 0.5) * CELL_M - self.centres[:, 1, None, None])
        listed = ((apart < limit[:, None, None]) & (cx >= 0) & (cx < shape[0]) & (cy >= 0)
                  & (cy < shape[1]))
        j, _, _ = np.nonzero(listed)
        cell = cx[listed] * shape[1] + cy[listed]
        order = np.lexsort((j, cell))  # by cell, then by cylinder
        cell, j = cell[order], j[order]
        first = np.searchsorted(cell, cell)  # each pair's cell's first pair
        rank = np.arange(len(cell)) - first
        table = np.full((int(shape[0] * shape[1]) + 1, int(rank.max()) + 1), -1, dtype=np.int64)
        table[cell, rank] = j
        self._low, self._shape, self._table = low, (int(shape[0]), int(shape[1])), table

    def correct(self, correction: Pose, odom_pose: Pose, ranges: np.ndarray,
                origin: np.ndarray, directions: np.ndarray) -> Pose:
        stride = -(-len(ranges) // self.max_beams)  # every stride-th beam, from the first
        if self.compiled:
            ok, x, y, yaw = _compiled_correct(
                (float(correction[0]), float(correction[1]), float(correction[2])),
                (float(odom_pose[0]), float(odom_pose[1]), float(odom_pose[2])),
                np.ascontiguousarray(ranges, dtype=float), np.ascontiguousarray(origin, float),
                np.ascontiguousarray(directions, dtype=float), self.centres, self.radii,
                self._table, self._low[0], self._low[1], self._shape[0], self._shape[1],
                CELL_M, self.gate_m, self.min_hits, self.steps, stride)
            return (x, y, yaw) if ok else correction
        r = np.asarray(ranges, dtype=float)[::stride]
        hit = np.isfinite(r)
        if hit.sum() < self.min_hits:
            return correction
        base = origin + r[hit, None] * np.asarray(directions, dtype=float)[::stride][hit]
        c, s = math.cos(odom_pose[2]), math.sin(odom_pose[2])
        odom = np.stack([odom_pose[0] + c * base[:, 0] - s * base[:, 1],
                         odom_pose[1] + s * base[:, 0] + c * base[:, 1]], axis=1)
        for _ in range(self.steps):
            ok, x, y, yaw = self._numpy_step(correction, odom, compose(correction, odom_pose))
            if not ok:
                break
            correction = (x, y, yaw)
        return correction

    def _numpy_step(self, correction: Pose, odom: np.ndarray, at: Pose) -> tuple:
        """``solve_step`` from the hits ``odom`` (odometry's frame), numpy's way."""
        c, s = math.cos(correction[2]), math.sin(correction[2])
        px = correction[0] + c * odom[:, 0] - s * odom[:, 1]
        py = correction[1] + s * odom[:, 0] + c * odom[:, 1]
        gx = np.floor((px - self._low[0]) / CELL_M)
        gy = np.floor((py - self._low[1]) / CELL_M)
        nx, ny = self._shape
        inside = (gx >= 0) & (gx < nx) & (gy >= 0) & (gy < ny)
        cell = np.where(inside, gx * ny + gy, nx * ny).astype(np.int64)
        listed = self._table[cell]  # (N, K)
        dx = px[:, None] - self.centres[listed, 0]
        dy = py[:, None] - self.centres[listed, 1]
        d = np.sqrt(dx * dx + dy * dy)
        gap = np.where(listed >= 0, d - self.radii[listed], np.inf)
        best = np.argmin(gap, axis=1)[:, None]
        gap = np.take_along_axis(gap, best, 1)[:, 0]
        d, dx, dy = (np.take_along_axis(a, best, 1)[:, 0] for a in (d, dx, dy))
        near = (np.abs(gap) < self.gate_m) & (d > 0.0)
        if near.sum() < self.min_hits:
            return False, correction[0], correction[1], correction[2]
        e, d = gap[near], d[near]
        n0, n1 = dx[near] / d, dy[near] / d  # outward normals
        m = n1 * (px[near] - at[0]) - n0 * (py[near] - at[1])
        terms = np.stack([n0 * n0, n0 * n1, n0 * m, n1 * n1, n1 * m, m * m,
                          n0 * e, n1 * e, m * e], axis=1)
        sums = np.cumsum(terms, axis=0)[-1]  # in the hits' order, as the compiled loop
        return solve_step(tuple(sums.tolist()), at, correction)


class Localizer:
    """One robot's localization on a known map, as amcl runs beside move_base: ``locate(odom,
    scan, ranges)`` corrects map -> odom with the scan ``scan`` (any key that differs from one
    scan to the next: a stamp) unless that scan was matched already, and is the pose on the
    map. The single env has one; the batch one per car, in the same order of calls."""

    def __init__(self, matcher: ScanMatcher, origin: np.ndarray,
                 directions: np.ndarray) -> None:
        self.matcher = matcher
        self._beams = (origin, directions)  # ``beam_geometry``'s
        #: map -> odom (x, y, yaw): the identity at the start (the map's origin)
        self.correction: Pose = IDENTITY
        self._scan: object = None  # the key of the scan matched last

    def match(self, odom_pose: Pose, scan: object, ranges: np.ndarray) -> None:
        """The correction after the scan ``scan`` (``ranges``, taken at ``odom_pose``), once."""
        if scan != self._scan:
            self.correction = self.matcher.correct(self.correction, odom_pose, ranges,
                                                   *self._beams)
            self._scan = scan

    def locate(self, odom_pose: Pose, scan: object, ranges: np.ndarray) -> Pose:
        """Base_link on the map after ``match``."""
        self.match(odom_pose, scan, ranges)
        return compose(self.correction, odom_pose)


def _correct_loops(correction, odom_pose, ranges, origin, directions, centres, radii, table,
                   low_x, low_y, nx, ny, cell, gate, min_hits, steps, stride):
    """``ScanMatcher.correct``, compiled: ``(ok, x, y, yaw)``, ``ok`` False where the
    correction stays."""
    b = ranges.shape[0]
    ox = np.empty(b)
    oy = np.empty(b)
    n = place_returns_compiled(odom_pose, ranges, origin, directions, stride, ox, oy)
    if n < min_hits:
        return False, correction[0], correction[1], correction[2]
    changed = False
    for _ in range(steps):
        at = compose_compiled(correction, odom_pose)
        c, s = math.cos(correction[2]), math.sin(correction[2])
        sums = np.zeros(9)
        paired = 0
        for k in range(n):
            px = correction[0] + c * ox[k] - s * oy[k]
            py = correction[1] + s * ox[k] + c * oy[k]
            gx = np.floor((px - low_x) / cell)
            gy = np.floor((py - low_y) / cell)
            row = nx * ny
            if gx >= 0 and gx < nx and gy >= 0 and gy < ny:
                row = int(gx * ny + gy)
            best, bd, bdx, bdy = np.inf, 0.0, 0.0, 0.0
            for q in range(table.shape[1]):
                j = table[row, q]
                if j < 0:
                    break
                dx = px - centres[j, 0]
                dy = py - centres[j, 1]
                d = math.sqrt(dx * dx + dy * dy)
                g = d - radii[j]
                if g < best:
                    best, bd, bdx, bdy = g, d, dx, dy
            if not (abs(best) < gate and bd > 0.0):
                continue
            n0, n1 = bdx / bd, bdy / bd
            add_residual_compiled(sums, paired == 0, n0, n1,
                                  n1 * (px - at[0]) - n0 * (py - at[1]), best)
            paired += 1
        if paired < min_hits:
            break
        ok, x, y, yaw = solve_sums_compiled(sums, at, correction)
        if not ok:
            break
        correction = (x, y, yaw)
        changed = True
    return changed, correction[0], correction[1], correction[2]


if COMPILED:
    #: ``compose``, ``solve_step``, ``place_returns``, ``add_residual`` and ``solve_sums`` for
    #: compiled loops
    #: (here and in ``scan_map``)
    compose_compiled = numba.njit(cache=True)(compose)
    solve_step_compiled = numba.njit(cache=True)(solve_step)
    add_residual_compiled = numba.njit(cache=True)(add_residual)
    place_returns_compiled = numba.njit(cache=True)(place_returns)
    solve_sums_compiled = numba.njit(cache=True)(solve_sums)
    _compiled_correct = numba.njit(cache=True, nogil=True)(_correct_loops)
