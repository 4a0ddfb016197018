"""N robots' ``paths.PathTracker`` at once: the batched BARN env's waypoints and path progress,
and the DWA driver's local goals and path windows.

``PathTrackers`` keeps N paths (padded rows) and each robot's nearest point. With numba (the
``fast`` extra) one compiled pass serves all the robots asked for; without it each robot has
its ``PathTracker``. Both give ``PathTracker``'s numbers bit for bit
(``tests/test_barn_env.py``): the same searches, the same float operations in the same order,
``np.interp``'s rule for a point between two of the path's, and ``math.cos`` where
``paths.to_base_frame`` takes it.
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

from smartcar_gym.navigation.paths import PathTracker, to_base_frame

#: whether the compiled passes are used (numba installed and ``SMARTCAR_GYM_NUMBA`` not ``0``)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"


class PathTrackers:
    """``num`` robots' path trackers with ``lookahead_m`` and ``window_m`` (``PathTracker``'s):
    ``start(i, path)`` gives robot i a path and starts it at the path's start, then
    ``waypoints``, ``to_go`` and ``windows`` per step."""

    def __init__(self, num: int, lookahead_m: float, window_m: float = 1.0,
                 compiled: bool | None = None) -> None:
        self.lookahead_m, self.window_m = float(lookahead_m), float(window_m)
        self.compiled = COMPILED if compiled is None else compiled
        if self.compiled and not COMPILED:
            raise RuntimeError('the compiled path trackers need numba: pip install '
                               '"smartcar-gym[fast]"')
        #: without numba: each robot's tracker
        self.trackers: list[PathTracker | None] = [None] * num
        # with numba: the paths as rows, their arc lengths, sizes and nearest points
        self.path = np.zeros((num, 1, 2))
        self.arc = np.zeros((num, 1))
        self.size = np.zeros(num, dtype=np.int64)
        self.nearest = np.zeros(num, dtype=np.int64)

    def start(self, i: int, path: np.ndarray) -> None:
        """Robot ``i`` follows ``path`` (M, 2) from its start."""
        tracker = PathTracker(path, self.lookahead_m, self.window_m)
        if not self.compiled:
            self.trackers[i] = tracker
            return
        m = len(tracker.path)
        if m > self.path.shape[1]:
            grow = m - self.path.shape[1]
            self.path = np.pad(self.path, ((0, 0), (0, grow), (0, 0)))
            self.arc = np.pad(self.arc, ((0, 0), (0, grow)))
        self.path[i, :m], self.arc[i, :m], self.size[i] = tracker.path, tracker.arc, m
        self.nearest[i] = 0

    def index(self, i: int) -> int:
        """Robot ``i``'s nearest point of its path (its index)."""
        return self.trackers[i].index if not self.compiled else int(self.nearest[i])

    def _rows(self, slots: Sequence[int]) -> np.ndarray:
        """``slots`` as an index array; ValueError naming a robot not started."""
        slots = np.asarray(slots, dtype=np.int64)
        started = (self.size[slots] > 0 if self.compiled
                   else np.array([self.trackers[i] is not None for i in slots.tolist()]))
        if len(slots) and not started.all():
            raise ValueError(f"robot {int(slots[~started][0])} has no path: start(i, path) "
                             "first")
        return slots

    def waypoints(self, slots: Sequence[int], xy: np.ndarray) -> np.ndarray:
        """(K, 2): each robot's next waypoint (odom frame) from ``xy`` (K, 2) (``waypoint``)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        slots = self._rows(slots)
        if not self.compiled:
            return np.array([self.trackers[i].waypoint(p) for i, p in zip(slots.tolist(), xy,
                                                                           strict=True)])
        out = np.empty((len(xy), 2))
        _waypoints(slots, xy, self.path, self.arc, self.size, self.nearest,
                   self.lookahead_m, self.window_m, out)
        return out

    def waypoints_in_base(self, slots: Sequence[int], poses: np.ndarray) -> np.ndarray:
        """(K, 2): each robot's next waypoint in the base frame of ``poses`` (K, 3), as
        ``paths.to_base_frame`` turns it (``math.cos``)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        slots = self._rows(slots)
        if not self.compiled:
            return np.array([to_base_frame(self.trackers[i].waypoint(p[:2]), *map(float, p))
                             for i, p in zip(slots.tolist(), poses, strict=True)]
                            ).reshape(-1, 2)
        out = np.empty((len(poses), 2))
        _waypoints(slots, np.ascontiguousarray(poses[:, :2]), self.path, self.arc,
                   self.size, self.nearest, self.lookahead_m, self.window_m, out)
        _to_base_frame(out, poses)
        return out

    def to_go(self, slots: Sequence[int], xy: np.ndarray) -> np.ndarray:
        """(K,): each robot's distance to its path's end along it (``to_go``)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        slots = self._rows(slots)
        if not self.compiled:
            return np.array([self.trackers[i].to_go(p) for i, p in zip(slots.tolist(), xy,
                                                                       strict=True)])
        out = np.empty(len(xy))
        _to_go(slots, xy, self.path, self.arc, self.size, self.nearest,
               self.window_m, out)
        return out

    def windows(self, slots: Sequence[int], poses: np.ndarray, cos: np.ndarray,
                sin: np.ndarray, behind_m: float, ahead_m: float, pad_m: float) -> np.ndarray:
        """(K, max W, 2): each robot's path from ``behind_m`` behind its nearest point to
        ``ahead_m`` ahead (at least that point), in the base frame of ``poses`` (K, 3) whose
        headings' cosines and sines are given; padded with points at (``pad_m``, ``pad_m``)."""
        rows = []
        slots = self._rows(slots)
        if not self.compiled:
            for i, pose, c, s in zip(slots.tolist(), poses, cos, sin, strict=True):
                t = self.trackers[i]
                lo = int(np.searchsorted(t.arc, t.arc[t.index] - behind_m))
                hi = int(np.searchsorted(t.arc, t.arc[t.index] + ahead_m, side="right"))
                d = t.path[lo:max(hi, lo + 1)] - pose[:2]
                rows.append(np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]],
                                     -1))
            out = np.full((len(rows), max(1, max(len(r) for r in rows)), 2), pad_m)
            for k, r in enumerate(rows):
                out[k, :len(r)] = r
            return out
        out = np.full((len(slots), max(1, int(self.size[slots].max())), 2), pad_m)
        counts = np.zeros(len(slots), dtype=np.int64)
        _windows(slots, np.asarray(poses, dtype=float), np.asarray(cos, dtype=float),
                 np.asarray(sin, dtype=float), self.path, self.arc, self.size,
                 self.nearest, behind_m, ahead_m, out, counts)
        return out[:, :max(1, int(counts.max()))]


# -- the compiled passes --------------------------------------------------------------------
def _advance(path, arc, size, index, i, x, y, window):
    """``PathTracker.waypoint``'s advance for robot ``i`` at (x, y): moves ``index[i]``; the
    distance."""
    m = size[i]
    limit = arc[i, index[i]] + window
    end = np.searchsorted(arc[i, :m], limit, side="right")
    best, nearest = math.inf, 0
    for j in range(index[i], end):
        dx = path[i, j, 0] - x
        dy = path[i, j, 1] - y
        d = math.sqrt(dx * dx + dy * dy)
        if d < best:
            best, nearest = d, j - index[i]
    index[i] += nearest
    return best


def _interp(arc, values, m, s):
    """``np.interp(s, arc[:m], values[:m])`` for ``s`` within the arc (compiled_base.c)."""
    if m == 1:
        return values[0]
    j = np.searchsorted(arc[:m], s, side="right") - 1
    if j >= m - 1 or arc[j] == s:
        return values[min(j, m - 1)]
    slope = (values[j + 1] - values[j]) / (arc[j + 1] - arc[j])
    out = slope * (s - arc[j]) + values[j]
    if out != out:  # nan one way: the other (numpy's rule)
        out = slope * (s - arc[j + 1]) + values[j + 1]
        if out != out and values[j] == values[j + 1]:
            out = values[j]
    return out


def _waypoints_loops(slots, xy, path, arc, size, index, lookahead, window, out):
    """``PathTracker.waypoint`` for each robot of ``slots`` into ``out``."""
    for k in range(len(slots)):
        i = slots[k]
        _advance(path, arc, size, index, i, xy[k, 0], xy[k, 1], window)
        m = size[i]
        s = min(max(arc[i, index[i]] + lookahead, 0.0), arc[i, m - 1])
        out[k, 0] = _interp(arc[i], path[i, :, 0], m, s)
        out[k, 1] = _interp(arc[i], path[i, :, 1], m, s)


def _to_base_frame_loops(points, poses):
    """``paths.to_base_frame`` of each row of ``points``, in place."""
    for k in range(len(points)):
        dx, dy = points[k, 0] - poses[k, 0], points[k, 1] - poses[k, 1]
        c, s = math.cos(poses[k, 2]), math.sin(poses[k, 2])
        points[k, 0], points[k, 1] = c * dx + s * dy, -s * dx + c * dy


def _to_go_loops(slots, xy, path, arc, size, index, window, out):
    """``PathTracker.to_go`` for each robot of ``slots`` into ``out``."""
    for k in range(len(slots)):
        i = slots[k]
        d = _advance(path, arc, size, index, i, xy[k, 0], xy[k, 1], window)
        out[k] = (arc[i, size[i] - 1] - arc[i, index[i]]) + d


def _windows_loops(slots, poses, cos, sin, path, arc, size, index, behind, ahead, out,
                   counts):
    """``PathTrackers.windows`` for each robot of ``slots`` into ``out`` and ``counts``."""
    for k in range(len(slots)):
        i = slots[k]
        m = size[i]
        here = arc[i, index[i]]
        lo = np.searchsorted(arc[i, :m], here - behind)
        hi = max(np.searchsorted(arc[i, :m], here + ahead, side="right"), lo + 1)
        c, s = cos[k], sin[k]
        for j in range(lo, hi):
            dx, dy = path[i, j, 0] - poses[k, 0], path[i, j, 1] - poses[k, 1]
            out[k, j - lo, 0], out[k, j - lo, 1] = c * dx + s * dy, -s * dx + c * dy
        counts[k] = hi - lo


if COMPILED:
    _advance = numba.njit(cache=True)(_advance)
    _interp = numba.njit(cache=True)(_interp)
    _waypoints = numba.njit(cache=True)(_waypoints_loops)
    _to_base_frame = numba.njit(cache=True)(_to_base_frame_loops)
    _to_go = numba.njit(cache=True)(_to_go_loops)
    _windows = numba.njit(cache=True)(_windows_loops)
