"""The local costmap's obstacle layer as DWA reads it: laser returns marked in the odom frame,
kept for a number of scans, read back near the robot in its base frame.

A square cell of ``cell_m`` is marked by a laser return in it and stays marked for ``scans``
scans after the last one, at that return's point (the first of the scan's returns in the
cell), so that an obstacle stays in the map when it comes closer than the laser's range_min
(or behind what the laser sees). With ``clearing`` (costmap_2d's ``clearing: true``, on by
default, as the challenge's Jackal sets it) each scan first clears the marked cells its beams
pass through: a marked point whose nearest beam returns farther than the point's distance plus
a cell, within half a cell of the beam's line. A beam that returns nothing (``+inf``, as
costmap_2d's ``inf_is_valid: false``) or too close (``-inf``) clears nothing. With a
``footprint`` (costmap_2d's ``footprint_clearing_enabled``, true by default and not set by the
challenge) the marked points inside the robot's padded footprint at the scan's pose are
forgotten after the scan is marked, as ``ObstacleLayer::updateCosts`` sets the footprint's
cells FREE before the planner reads the costmap. Two ways, the same points bit for bit
(``tests/test_dwa.py``):

* ``ObstacleMemory``: one robot's layer in numpy (sorted cell keys);
* ``ObstacleLayers``: N robots' layers; with numba (the ``fast`` extra) in arrays, each
  robot's scan marked and its nearby points read in one compiled pass over the robots (the
  same sorted keys, the same float operations in the same order; ``threads``: the robots
  split over the cores, each robot's rows its own), else a row of ``ObstacleMemory``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

try:
    import numba
except ImportError:  # the fast extra is not installed
    numba = None

from smartcar_gym.navigation.beams import beam_of, doubt_band
from smartcar_gym.navigation.footprint import FAR_M
from smartcar_gym.parallel import run_chunks

#: whether ``ObstacleLayers`` runs compiled (numba installed, ``SMARTCAR_GYM_NUMBA`` not ``0``)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"
CELL_OFFSET = 1 << 30  # makes cell indices positive for the keys
SCANS = 50  # scans a cell stays marked after its last return
CELL_M = 0.005


def scan_points(ranges: np.ndarray, angles: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """A scan's returns as points (K, 2) in base_link (``mount``: the laser's 4 x 4 pose in
    it); ``+inf`` (nothing) and ``-inf`` (closer than range_min) are left out, as the
    costmap's obstacle layer leaves them."""
    r = np.asarray(ranges, dtype=float)
    keep = np.isfinite(r)
    x, y = r[keep] * np.cos(angles[keep]), r[keep] * np.sin(angles[keep])
    return np.stack([mount[0, 0] * x + mount[0, 1] * y + mount[0, 3],
                     mount[1, 0] * x + mount[1, 1] * y + mount[1, 3]], -1)


def to_odom(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 2) of the base frame of ``pose`` (x, y, theta) in the odom frame."""
    p = np.asarray(points, dtype=float)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.stack([c * p[..., 0] - s * p[..., 1] + pose[0],
                     s * p[..., 0] + c * p[..., 1] + pose[1]], -1)


def to_base(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 2) of the odom frame in the base frame of ``pose`` (x, y, theta)."""
    d = np.asarray(points, dtype=float) - pose[:2]
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], -1)


def mount_frame(mount: np.ndarray) -> np.ndarray:
    """The laser mount's 2D terms (m00, m01, m03, m10, m11, m13) of its 4 x 4 pose."""
    return np.array([mount[0, 0], mount[0, 1], mount[0, 3], mount[1, 0], mount[1, 1],
                     mount[1, 3]], dtype=float)


def beam_layout(angles: np.ndarray) -> tuple[float, float, bool]:
    """The first beam's angle, the step between beams (rad), and whether they go all round
    (the last beam is then the first's neighbour)."""
    angles = np.asarray(angles, dtype=float)
    step = float(angles[1] - angles[0]) if len(angles) > 1 else 2.0 * math.pi
    return float(angles[0]), step, len(angles) * step >= 2.0 * math.pi - 0.5 * step


def passed_through(points: np.ndarray, ranges: np.ndarray, angles: np.ndarray,
                   mount: np.ndarray, pose: np.ndarray, cell_m: float) -> np.ndarray:
    """Which ``points`` (M, 2), odom frame, a beam of the scan ``ranges`` (beam ``angles``,
    the laser at ``mount`` in base_link) taken at ``pose`` passes through (module
    docstring)."""
    m00, m01, m03, m10, m11, m13 = mount_frame(mount)
    first, step, round_ = beam_layout(angles)
    beam_cos, beam_sin = np.cos(angles), np.sin(angles)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    dx, dy = points[:, 0] - pose[0], points[:, 1] - pose[1]
    bx = c * dx + s * dy - m03
    by = -s * dx + c * dy - m13
    lx = m00 * bx + m10 * by
    ly = m01 * bx + m11 * by
    j = np.rint((np.arctan2(ly, lx) - first) / step).astype(np.int64)
    beams = len(ranges)
    seen = np.ones(len(j), dtype=bool) if round_ else (j >= 0) & (j < beams)
    j = j % beams
    r = ranges[j]
    along = lx * beam_cos[j] + ly * beam_sin[j]
    across = ly * beam_cos[j] - lx * beam_sin[j]
    return seen & np.isfinite(r) & (along < r - cell_m) & (np.abs(across) < 0.5 * cell_m)


def pad(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """(N, max K, 2) of N (K_i, 2) arrays, padded with points ``FAR_M`` away."""
    size = max(1, max(len(a) for a in arrays))
    out = np.full((len(arrays), size, 2), FAR_M)
    for i, a in enumerate(arrays):
        out[i, :len(a)] = a
    return out


class ObstacleMemory:
    """One robot's obstacle layer (module docstring), in numpy."""

    def __init__(self, scans: int = SCANS, cell_m: float = CELL_M) -> None:
        self.scans = scans
        self.cell_m = cell_m
        self.count = 0  # scans marked so far
        self.keys = np.zeros(0, dtype=np.int64)  # the marked cells, sorted
        self.points = np.zeros((0, 2))
        self.seen = np.zeros(0, dtype=np.int64)  # the scan that last marked each

    def add(self, points: np.ndarray) -> None:
        """Mark the cells of ``points`` (K, 2), odom frame, and forget the cells no scan of
        the last ``scans`` marked."""
        self.count += 1
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        cells = np.floor(points / self.cell_m).astype(np.int64) + CELL_OFFSET
        keys, first = np.unique(cells[:, 0] * (2 * CELL_OFFSET) + cells[:, 1],
                                return_index=True)
        at = np.minimum(np.searchsorted(self.keys, keys), max(len(self.keys) - 1, 0))
        known = (self.keys[at] == keys) if len(self.keys) else np.zeros(len(keys), dtype=bool)
        self.points[at[known]] = points[first[known]]
        self.seen[at[known]] = self.count
        keys = np.concatenate([self.keys, keys[~known]])
        order = np.argsort(keys, kind="stable")
        fresh = np.concatenate([self.seen, np.full(int((~known).sum()), self.count)])[order]
        keep = fresh > self.count - self.scans
        self.keys = keys[order][keep]
        self.points = np.concatenate([self.points, points[first[~known]]])[order][keep]
        self.seen = fresh[keep]

    def clear_through(self, ranges: np.ndarray, angles: np.ndarray, mount: np.ndarray,
                      pose: np.ndarray) -> None:
        """Forget the marked cells the beams of a scan taken at ``pose`` (odom) pass through
        (``passed_through``)."""
        if len(self.keys):
            keep = ~passed_through(self.points, np.asarray(ranges, dtype=float), angles, mount,
                                   pose, self.cell_m)
            self.keys, self.points, self.seen = self.keys[keep], self.points[keep], self.seen[keep]

    def clear_footprint(self, pose: np.ndarray, half_x: float, half_y: float) -> None:
        """Forget the marked points inside the footprint rectangle of half extents ``half_x``,
        ``half_y`` (padding in) about ``pose`` (x, y, theta) in odom."""
        if len(self.keys):
            points = to_base(self.points, pose)
            keep = ~((np.abs(points[:, 0]) < half_x) & (np.abs(points[:, 1]) < half_y))
            self.keys, self.points, self.seen = self.keys[keep], self.points[keep], self.seen[keep]

    def near(self, pose: np.ndarray, reach_m: float) -> np.ndarray:
        """The marked points within ``reach_m`` of ``pose`` (x, y, theta), in its base frame."""
        points = to_base(self.points, pose)
        return points[points[:, 0] ** 2 + points[:, 1] ** 2 < reach_m * reach_m]


class ObstacleLayers:
    """N robots' obstacle layers: ``clear(i)`` when robot i starts again, then per step
    ``update(slots, ranges, poses, ...)``, which clears what each listed robot's scan passes
    through (``clearing``), marks the scan, forgets the points inside the robot's footprint
    (``footprint``) and returns the points near it (padded, with their counts) as
    ``ObstacleMemory`` does."""

    def __init__(self, num: int, scans: int = SCANS, cell_m: float = CELL_M,
                 compiled: bool | None = None, clearing: bool = True, threads: int = 1) -> None:
        self.scans, self.cell_m = scans, cell_m
        self.threads = threads  # the compiled pass's robots split over these (parallel.py)
        self.clearing = clearing
        self.compiled = COMPILED if compiled is None else compiled
        if self.compiled and not COMPILED:
            raise RuntimeError('the compiled obstacle layers need numba: pip install '
                               '"smartcar-gym[fast]"')
        self.memories = [ObstacleMemory(scans, cell_m) for _ in range(num)]
        self.size = np.zeros(num, dtype=np.int64)
        self.count = np.zeros(num, dtype=np.int64)
        self._near = np.empty((0, 0, 2))  # the compiled pass's output rows
        self._grow(num, 0)

    def _grow(self, num: int, capacity: int) -> None:
        """Room for ``capacity`` cells per robot (the marked ones kept)."""
        keys, points, seen = (np.zeros((num, capacity), dtype=np.int64),
                              np.zeros((num, capacity, 2)), np.zeros((num, capacity),
                                                                     dtype=np.int64))
        if hasattr(self, "keys"):
            old = self.keys.shape[1]
            keys[:, :old], points[:, :old], seen[:, :old] = self.keys, self.points, self.seen
        self.keys, self.points, self.seen = keys, points, seen

    def clear(self, i: int) -> None:
        """Robot ``i`` starts with an empty layer."""
        self.memories[i] = ObstacleMemory(self.scans, self.cell_m)
        self.size[i] = self.count[i] = 0

    def update(self, slots: Sequence[int], ranges: np.ndarray, angles: np.ndarray,
               mount: np.ndarray, poses: np.ndarray, reach_m: float,
               footprint: tuple[float, float] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """Clear (``clearing``) and mark with the scans ``ranges`` (K, B) of robots ``slots``
        (beam ``angles``, the laser at ``mount`` in base_link) taken at ``poses`` (K, 3) in
        odom, then forget the points inside each robot's ``footprint`` there (its half extents
        with the padding, base frame; None: none forgotten); the points of each within
        ``reach_m`` in its base frame, ``(K, max P, 2)`` padded ``FAR_M`` away, and P (K,)."""
        poses = np.asarray(poses, dtype=float)
        half_x, half_y = (0.0, 0.0) if footprint is None else (float(h) for h in footprint)
        if footprint is not None and not (half_x > 0.0 and half_y > 0.0):
            raise ValueError(f"footprint half extents must be > 0 m, got {footprint!r}")
        if not self.compiled:
            near = []
            for k, i in enumerate(slots):
                memory = self.memories[i]
                if self.clearing:
                    memory.clear_through(ranges[k], angles, mount, poses[k])
                memory.add(to_odom(scan_points(ranges[k], angles, mount), poses[k]))
                if footprint is not None:
                    memory.clear_footprint(poses[k], half_x, half_y)
                near.append(memory.near(poses[k], reach_m))
            return pad(near), np.array([len(p) for p in near], dtype=np.int64)
        slots = np.asarray(slots, dtype=np.int64)
        ranges = np.ascontiguousarray(ranges, dtype=float)
        beams = ranges.shape[1]
        if len(slots) and int(self.size[slots].max()) + beams > self.keys.shape[1]:
            self._grow(len(self.size), 2 * (int(self.size.max()) + beams))
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        frame = mount_frame(mount)
        first, step, round_ = beam_layout(angles)
        width = max(1, int(self.size[slots].max(initial=0)) + beams)
        if self._near.shape[0] < len(slots) or self._near.shape[1] < width:
            self._near = np.empty((max(len(slots), self._near.shape[0]), 2 * width, 2))
        counts = np.zeros(len(slots), dtype=np.int64)
        beam_cos, beam_sin = np.cos(angles), np.sin(angles)

        def work(a: int, b: int) -> None:
            _compiled_update(slots[a:b], ranges[a:b], beam_cos, beam_sin, frame, poses[a:b],
                             cos[a:b], sin[a:b], self.keys, self.points, self.seen, self.size,
                             self.count, self.scans, self.cell_m, reach_m, self._near[a:b],
                             counts[a:b], self.clearing, first, step, doubt_band(step), round_,
                             footprint is not None, half_x, half_y)

        run_chunks(work, len(slots), self.threads)
        near = self._near[:len(slots), :max(1, int(counts.max(initial=0)))].copy()
        near[np.arange(near.shape[1]) >= counts[:, None]] = FAR_M
        return near, counts

    def points_of(self, i: int) -> np.ndarray:
        """Robot ``i``'s marked points (odom frame), in key order."""
        if not self.compiled:
            return self.memories[i].points
        return self.points[i, :self.size[i]]


def _update_loops(slots, ranges, beam_cos, beam_sin, frame, poses, cos, sin, keys, points,
                  seen, size, count, scans, cell_m, reach, near, counts, clearing, first, step,
                  band, round_, footprint, half_x, half_y):
    """``ObstacleMemory.clear_through`` (with ``clearing``), ``add``, ``clear_footprint``
    (with ``footprint``) and ``near`` for each robot of ``slots`` (see ``update``); each
    point's beam by ``beams.beam_of`` (numpy's ``rint`` of the ``arctan2`` formula, to the
    bit, its angle doubted within ``band`` beams of a half-way point)."""
    b = ranges.shape[1]
    m00, m01, m03, m10, m11, m13 = frame[0], frame[1], frame[2], frame[3], frame[4], frame[5]
    new_x = np.empty(b)
    new_y = np.empty(b)
    new_key = np.empty(b, dtype=np.int64)
    merged_key = np.empty(keys.shape[1], dtype=np.int64)
    merged_pt = np.empty((keys.shape[1], 2))
    merged_seen = np.empty(keys.shape[1], dtype=np.int64)
    reach2 = reach * reach
    for k in range(len(slots)):
        i = slots[k]
        count[i] += 1
        now = count[i]
        px, py, c, s = poses[k, 0], poses[k, 1], cos[k], sin[k]
        if clearing:  # passed_through, the kept cells moved up in place
            kept = 0
            for e in range(size[i]):
                dx, dy = points[i, e, 0] - px, points[i, e, 1] - py
                bx = c * dx + s * dy - m03
                by = -s * dx + c * dy - m13
                lx = m00 * bx + m10 * by
                ly = m01 * bx + m11 * by
                j = beam_of(lx, ly, first, step, band)
                through = round_ or (j >= 0 and j < b)
                if not 0 <= j < b:  # the beam's index modulo b (an integer division)
                    j = j % b
                r = ranges[k, j]
                along = lx * beam_cos[j] + ly * beam_sin[j]
                across = ly * beam_cos[j] - lx * beam_sin[j]
                if (through and math.isfinite(r) and along < r - cell_m
                        and abs(across) < 0.5 * cell_m):
                    continue
                keys[i, kept], seen[i, kept] = keys[i, e], seen[i, e]
                points[i, kept, 0], points[i, kept, 1] = points[i, e, 0], points[i, e, 1]
                kept += 1
            size[i] = kept
        # the scan's returns in odom (scan_points, to_odom) and their cells
        q = 0
        for j in range(b):
            r = ranges[k, j]
            if not math.isfinite(r):
                continue
            x, y = r * beam_cos[j], r * beam_sin[j]
            bx = m00 * x + m01 * y + m03
            by = m10 * x + m11 * y + m13
            ox = c * bx - s * by + px
            oy = s * bx + c * by + py
            new_x[q], new_y[q] = ox, oy
            cx = np.int64(math.floor(ox / cell_m)) + CELL_OFFSET
            cy = np.int64(math.floor(oy / cell_m)) + CELL_OFFSET
            new_key[q] = cx * (2 * CELL_OFFSET) + cy
            q += 1
        order = np.argsort(new_key[:q], kind="mergesort")  # stable: a cell's first return
        # merge the sorted unique new keys into the robot's sorted keys, then forget
        old, a, out, u = size[i], 0, 0, 0
        while a < old or u < q:
            if u < q and u > 0 and new_key[order[u]] == new_key[order[u - 1]]:
                u += 1  # a later return in a cell already taken
                continue
            if u >= q or (a < old and keys[i, a] < new_key[order[u]]):
                key, x, y, last = keys[i, a], points[i, a, 0], points[i, a, 1], seen[i, a]
                a += 1
            else:
                key, x, y, last = new_key[order[u]], new_x[order[u]], new_y[order[u]], now
                if a < old and keys[i, a] == key:
                    a += 1  # the cell was marked: this return is its point now
                u += 1
            if last > now - scans:
                merged_key[out], merged_seen[out] = key, last
                merged_pt[out, 0], merged_pt[out, 1] = x, y
                out += 1
        n = 0
        kept = 0
        for e in range(out):
            # to_base: clear_footprint's test, then near's
            dx, dy = merged_pt[e, 0] - px, merged_pt[e, 1] - py
            lx = c * dx + s * dy
            ly = -s * dx + c * dy
            if footprint and abs(lx) < half_x and abs(ly) < half_y:
                continue
            keys[i, kept], seen[i, kept] = merged_key[e], merged_seen[e]
            points[i, kept, 0], points[i, kept, 1] = merged_pt[e, 0], merged_pt[e, 1]
            kept += 1
            if lx * lx + ly * ly < reach2:  # numpy's ** 2 is a product
                near[k, n, 0], near[k, n, 1] = lx, ly
                n += 1
        size[i] = kept
        counts[k] = n


if COMPILED:
    _compiled_update = numba.njit(cache=True, nogil=True)(_update_loops)
