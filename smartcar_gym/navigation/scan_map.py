"""Localization without a map: each car's scans matched to the map its own earlier scans made.

Without a map a ROS robot's odometry drifts and nothing puts it back; a laser SLAM front end
(gmapping, cartographer, hector's scan matcher) publishes the ``map -> odom`` transform that
does, from the laser alone. ``ScanMaps`` is that front end for N cars, one map each: a map
keeps one laser return per cell of a grid (the laser costmap's: the same corner, cells and
resolution), the first to land in it, at a 1/255 cell's precision. Each new scan's returns
are placed through the current correction and the odometry pose and matched to the map by
point-to-line ICP (Censi's PL-ICP, as the ROS ``laser_scan_matcher`` runs it): each return is
paired with its two nearest kept returns within ``gate_m`` (the cells within the gate searched
ring by ring, the first nearest kept on a tie), its residual its distance from the line
through them, and a Gauss-Newton step (``localization.solve_step``, about the car) moves the
correction to bring the returns onto their lines, up to ``iterations`` times or until a step
moves the car less than ``TOLERANCE`` (m, and rad). With fewer than ``min_pairs`` pairs the
correction stays. The scan's returns are then kept where their cells are empty, at the
corrected pose. The first scan (an empty map) keeps its returns at the odometry's pose: the
map's frame is the odom frame at the start. No ground truth is read.

Two ways, the same numbers bit for bit (``tests/test_scan_map.py``): numpy, and numba's loops
(the ``fast`` extra, one car's scan in some tens of microseconds) over the cars split across
threads. Both sum the normal equations in the returns' order (numpy's ``cumsum``, not a
pairwise sum), take cosines and sines from ``math``, compare squared distances and solve with
the same scalar Cholesky, so the maps and corrections do not depend on the machine's BLAS or
on the thread count.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from smartcar_gym import checks
from smartcar_gym.navigation.costmap import MAX_TOTAL_CELLS, CostmapConfig
from smartcar_gym.navigation.localization import COMPILED, Pose, compose, solve_step
from smartcar_gym.parallel import run_chunks

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

GATE_M = 0.05  # a return this far from every kept one is unpaired (m)
MIN_PAIRS = 40  # fewer pairs than this: the correction stays
ITERATIONS = 3  # ICP steps per scan at most
TOLERANCE = 1e-5  # a step that moves the car less than this (m, and rad) is the last
EMPTY = 255  # a cell's offset byte where it keeps no return
LEVELS = 255  # a kept return's offsets in a cell: 0 to LEVELS - 1, in 1/LEVELS of a cell


def _settled(before: Pose, after: Pose) -> bool:
    """Whether the car moved less than ``TOLERANCE`` from ``before`` to ``after``."""
    dx, dy = after[0] - before[0], after[1] - before[1]
    return dx * dx + dy * dy < TOLERANCE * TOLERANCE and abs(after[2] - before[2]) < TOLERANCE


class ScanMaps:
    """N cars' maps of their own laser returns and the scan-to-map matching on them (module
    docstring); ``grid``: the cells (``CostmapConfig``'s ``corner``, ``cells`` and
    ``resolution``: the laser costmap's). ``compiled``: None, numba where it is installed;
    False, numpy; True, numba or an error."""

    def __init__(self, grid: CostmapConfig, n: int, gate_m: float = GATE_M,
                 min_pairs: int = MIN_PAIRS, iterations: int = ITERATIONS,
                 compiled: bool | None = None) -> None:
        checks.positive_int("scan map cars", n)
        cells = grid.cells
        if n * cells * cells > MAX_TOTAL_CELLS:
            raise ValueError(f"scan map cars: {n} maps of {cells} x {cells} cells are more than "
                             f"{MAX_TOTAL_CELLS:,} cells")
        self.gate_m = checks.positive_number("scan map gate_m", gate_m)
        self.min_pairs = checks.positive_int("scan map min_pairs", min_pairs)
        self.iterations = checks.positive_int("scan map iterations", iterations)
        self.compiled = COMPILED if compiled is None else bool(compiled)
        if self.compiled and not COMPILED:
            raise RuntimeError('the compiled scan map needs numba: pip install '
                               '"smartcar-gym[fast]"')
        self.grid, self.n = grid, n
        # the cells within the gate of a return's cell, ring by ring about it (then row by
        # row), and the least squared distance from the return to a cell of each ring
        reach = math.ceil(self.gate_m / grid.resolution)
        dy, dx = (a.ravel() for a in np.mgrid[-reach:reach + 1, -reach:reach + 1])
        ring = np.maximum(np.abs(dx), np.abs(dy))
        order = np.argsort(ring, kind="stable")
        self._dx, self._dy = dx[order].astype(np.int64), dy[order].astype(np.int64)
        self._near2 = (np.maximum(ring[order] - 1, 0) * float(grid.resolution)) ** 2
        #: each car's kept returns: ``[car, iy, ix]`` their offsets in the cell (u, v), EMPTY
        self._offsets = np.full((n, cells, cells, 2), EMPTY, dtype=np.uint8)

    def reset(self, cars: Sequence[int] | np.ndarray) -> None:
        """Empties the maps of ``cars``: nothing seen."""
        self._offsets[checks.car_indices("scan map", cars, self.n)] = EMPTY

    def points(self, car: int) -> np.ndarray:
        """Car ``car``'s kept returns (P, 2: x, y, m in the map frame), by cell row."""
        offsets = self._offsets[checks.car_index("scan map", car, self.n)]
        iy, ix = np.nonzero(offsets[..., 0] != EMPTY)
        return self._decode(ix, iy, offsets[iy, ix, 0], offsets[iy, ix, 1])

    def _decode(self, ix: np.ndarray, iy: np.ndarray, u: np.ndarray,
                v: np.ndarray) -> np.ndarray:
        x0, y0 = self.grid.corner
        res = self.grid.resolution
        return np.stack([x0 + (ix + (u.astype(float) + 0.5) / LEVELS) * res,
                         y0 + (iy + (v.astype(float) + 0.5) / LEVELS) * res], axis=-1)

    def correct(self, cars: Sequence[int] | np.ndarray, corrections: np.ndarray,
                odom_poses: np.ndarray, ranges: np.ndarray, origin: np.ndarray,
                directions: np.ndarray, threads: int = 1) -> np.ndarray:
        """The corrections (K, 3: map -> odom x, y, yaw) of ``cars`` (K,) after one scan each
        (``ranges`` (K, B), REP 117: non-finite ranges hit nothing) taken at ``odom_poses``
        (K, 3) from their ``corrections`` (K, 3); the beams leave ``origin`` (2,) along
        ``directions`` (B, 2) in base_link (``localization.beam_geometry``). The scans'
        returns are then kept in the maps. The compiled loops split the cars over
        ``threads`` threads (the same numbers whatever the count)."""
        idx = checks.car_indices("scan map", cars, self.n)
        out = np.array(corrections, dtype=np.float64).reshape(len(idx), 3)
        odoms = np.ascontiguousarray(odom_poses, dtype=np.float64).reshape(len(idx), 3)
        directions = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 2)
        ranges = np.ascontiguousarray(ranges, dtype=np.float64).reshape(len(idx),
                                                                        len(directions))
        origin = np.ascontiguousarray(origin, dtype=np.float64).reshape(2)
        x0, y0 = self.grid.corner
        args = (self._offsets, x0, y0, float(self.grid.resolution), self.grid.cells, self._dx,
                self._dy, self._near2, self.gate_m * self.gate_m, self.min_pairs,
                self.iterations)
        if self.compiled:
            def work(a: int, b: int) -> None:
                _compiled_correct(idx[a:b], out[a:b], odoms[a:b], ranges[a:b], origin,
                                  directions, *args)

            run_chunks(work, len(idx), checks.positive_int("scan map threads", threads))
            return out
        for k, car in enumerate(idx.tolist()):
            ox, oy = _returns(odoms[k], ranges[k], origin, directions)
            out[k] = self._numpy_icp(car, tuple(out[k].tolist()), tuple(odoms[k].tolist()),
                                     ox, oy)
            self._numpy_keep(car, tuple(out[k].tolist()), ox, oy)
        return out

    def _numpy_icp(self, car: int, correction: Pose, odom: Pose, ox: np.ndarray,
                   oy: np.ndarray) -> Pose:
        """PL-ICP of the returns ``ox, oy`` (odom frame, taken at ``odom``) against car
        ``car``'s map, numpy's way."""
        x0, y0 = self.grid.corner
        res, n = self.grid.resolution, self.grid.cells
        offsets = self._offsets[car]
        gate2 = self.gate_m * self.gate_m
        for _ in range(self.iterations):
            at = compose(correction, odom)
            c, s = math.cos(correction[2]), math.sin(correction[2])
            px = correction[0] + c * ox - s * oy
            py = correction[1] + s * ox + c * oy
            cx = np.floor((px - x0) / res)[:, None] + self._dx[None, :]
            cy = np.floor((py - y0) / res)[:, None] + self._dy[None, :]
            inside = (cx >= 0) & (cx < n) & (cy >= 0) & (cy < n)
            ix = np.where(inside, cx, 0).astype(np.int64)
            iy = np.where(inside, cy, 0).astype(np.int64)
            u, v = offsets[iy, ix, 0], offsets[iy, ix, 1]
            kept = inside & (u != EMPTY)
            q = self._decode(ix, iy, u, v)
            ex, ey = q[..., 0] - px[:, None], q[..., 1] - py[:, None]
            d2 = np.where(kept, ex * ex + ey * ey, np.inf)
            two = np.argsort(d2, axis=1, kind="stable")[:, :2]  # the loops' first two nearest
            paired = np.take_along_axis(d2, two[:, 1:], 1)[:, 0] < gate2
            q1x, q2x = (np.take_along_axis(q[..., 0], two, 1)[paired].T)
            q1y, q2y = (np.take_along_axis(q[..., 1], two, 1)[paired].T)
            tx, ty = q2x - q1x, q2y - q1y
            length = np.sqrt(tx * tx + ty * ty)
            line = length > 0.0
            n0, n1 = -ty[line] / length[line], tx[line] / length[line]
            if len(n0) < self.min_pairs:
                break
            qx, qy, rx, ry = q1x[line], q1y[line], px[paired][line], py[paired][line]
            e = n0 * (rx - qx) + n1 * (ry - qy)
            m = n1 * (rx - at[0]) - n0 * (ry - at[1])
            terms = np.stack([n0 * n0, n0 * n1, n0 * m, n1 * n1, n1 * m, m * m,
                              n0 * e, n1 * e, m * e], axis=1)
            sums = np.cumsum(terms, axis=0)[-1]  # in the returns' order, as the loops
            ok, x, y, yaw = solve_step(tuple(sums.tolist()), at, correction)
            if not ok:
                break
            correction = (x, y, yaw)
            if _settled(at, compose(correction, odom)):
                break
        return correction

    def _numpy_keep(self, car: int, correction: Pose, ox: np.ndarray, oy: np.ndarray) -> None:
        """The returns ``ox, oy`` (odom frame) kept in car ``car``'s empty cells."""
        x0, y0 = self.grid.corner
        res, n = self.grid.resolution, self.grid.cells
        c, s = math.cos(correction[2]), math.sin(correction[2])
        fx = (correction[0] + c * ox - s * oy - x0) / res
        fy = (correction[1] + s * ox + c * oy - y0) / res
        gx, gy = np.floor(fx), np.floor(fy)
        inside = (gx >= 0) & (gx < n) & (gy >= 0) & (gy < n)
        ix, iy = gx[inside].astype(np.int64), gy[inside].astype(np.int64)
        u = np.minimum((fx[inside] - gx[inside]) * LEVELS, LEVELS - 1).astype(np.uint8)
        v = np.minimum((fy[inside] - gy[inside]) * LEVELS, LEVELS - 1).astype(np.uint8)
        offsets = self._offsets[car]
        empty = offsets[iy, ix, 0] == EMPTY
        _, first = np.unique(iy[empty] * n + ix[empty], return_index=True)  # the first return
        pick = np.flatnonzero(empty)[first]
        offsets[iy[pick], ix[pick], 0] = u[pick]
        offsets[iy[pick], ix[pick], 1] = v[pick]


def _returns(odom: np.ndarray, ranges: np.ndarray, origin: np.ndarray,
             directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A scan's returns (finite ranges) in the odom frame, from base_link at ``odom``."""
    hit = np.isfinite(ranges)
    r = ranges[hit]
    bx = origin[0] + r * directions[hit, 0]
    by = origin[1] + r * directions[hit, 1]
    c, s = math.cos(odom[2]), math.sin(odom[2])
    return odom[0] + c * bx - s * by, odom[1] + s * bx + c * by


def _correct_loops(idx, corrections, odoms, ranges, origin, directions, offsets, x0, y0, res,
                   n, dxs, dys, near2, gate2, min_pairs, iterations):
    """``ScanMaps.correct``, compiled: ``corrections`` (K, 3) written in place. A return's
    search stops at the first ring of cells no nearer than its nearest kept return so far
    (every later cell is further): numpy's first nearest over every cell all the same."""
    b = ranges.shape[1]
    ox, oy = np.empty(b), np.empty(b)
    reach = max(max(dxs.max(), dys.max()), 0)
    res2 = res * res
    for k in range(idx.shape[0]):
        car = idx[k]
        odom = (odoms[k, 0], odoms[k, 1], odoms[k, 2])
        count = place_returns_compiled(odom, ranges[k], origin, directions, 1, ox, oy)
        correction = (corrections[k, 0], corrections[k, 1], corrections[k, 2])
        for _ in range(iterations):
            at = compose_compiled(correction, odom)
            c, s = math.cos(correction[2]), math.sin(correction[2])
            sums = np.zeros(9)
            paired = 0
            for j in range(count):
                x = correction[0] + c * ox[j] - s * oy[j]
                y = correction[1] + s * ox[j] + c * oy[j]
                fx = (x - x0) / res
                fy = (y - y0) / res
                gx = np.floor(fx)
                gy = np.floor(fy)
                best, second = gate2, gate2  # the two nearest so far (squared), within the gate
                q1x, q1y, q2x, q2y = 0.0, 0.0, 0.0, 0.0
                if not (gx > -reach - 1 and gx < n + reach and gy > -reach - 1
                        and gy < n + reach):
                    continue  # no cell within the gate is on the grid
                gxi, gyi = int(gx), int(gy)
                inner = gxi >= reach and gxi < n - reach and gyi >= reach and gyi < n - reach
                ax, ay = fx - gx, fy - gy  # the return within its cell (0 to 1)
                for t in range(dxs.shape[0]):
                    if near2[t] >= second:  # every later cell is further
                        break
                    dx, dy = dxs[t], dys[t]
                    ix, iy = gxi + dx, gyi + dy
                    if not inner and not (ix >= 0 and ix < n and iy >= 0 and iy < n):
                        continue
                    # the least distance (cells) from the return to this cell: its points lie
                    # at least half a level inside it, so a cell no nearer than ``second`` holds
                    # nothing nearer (numpy's search reads it and finds nothing nearer)
                    lx = dx - ax if dx > 0 else (ax - dx - 1.0 if dx < 0 else 0.0)
                    ly = dy - ay if dy > 0 else (ay - dy - 1.0 if dy < 0 else 0.0)
                    if (lx * lx + ly * ly) * res2 >= second:
                        continue
                    u = offsets[car, iy, ix, 0]
                    if u == EMPTY:
                        continue
                    v = offsets[car, iy, ix, 1]
                    mx = x0 + (ix + (float(u) + 0.5) / LEVELS) * res
                    my = y0 + (iy + (float(v) + 0.5) / LEVELS) * res
                    ex, ey = mx - x, my - y
                    d2 = ex * ex + ey * ey
                    if d2 < best:
                        second, q2x, q2y = best, q1x, q1y
                        best, q1x, q1y = d2, mx, my
                    elif d2 < second:
                        second, q2x, q2y = d2, mx, my
                if not second < gate2:  # two found within the gate
                    continue
                tx, ty = q2x - q1x, q2y - q1y
                length = math.sqrt(tx * tx + ty * ty)
                if not length > 0.0:
                    continue
                n0, n1 = -ty / length, tx / length
                add_residual_compiled(sums, paired == 0, n0, n1,
                                      n1 * (x - at[0]) - n0 * (y - at[1]),
                                      n0 * (x - q1x) + n1 * (y - q1y))
                paired += 1
            if paired < min_pairs:
                break
            ok, x, y, yaw = solve_sums_compiled(sums, at, correction)
            if not ok:
                break
            correction = (x, y, yaw)
            if _settled_compiled(at, compose_compiled(correction, odom)):
                break
        corrections[k, 0], corrections[k, 1], corrections[k, 2] = correction
        c, s = math.cos(correction[2]), math.sin(correction[2])
        for j in range(count):
            fx = (correction[0] + c * ox[j] - s * oy[j] - x0) / res
            fy = (correction[1] + s * ox[j] + c * oy[j] - y0) / res
            gx, gy = np.floor(fx), np.floor(fy)
            if not (gx >= 0 and gx < n and gy >= 0 and gy < n):
                continue
            ix, iy = int(gx), int(gy)
            if offsets[car, iy, ix, 0] != EMPTY:
                continue
            offsets[car, iy, ix, 0] = np.uint8(min((fx - gx) * LEVELS, LEVELS - 1))
            offsets[car, iy, ix, 1] = np.uint8(min((fy - gy) * LEVELS, LEVELS - 1))


if COMPILED:
    from smartcar_gym.navigation.localization import (
        add_residual_compiled,
        compose_compiled,
        place_returns_compiled,
        solve_sums_compiled,
    )

    _settled_compiled = numba.njit(cache=True)(_settled)
    _compiled_correct = numba.njit(cache=True, nogil=True)(_correct_loops)
