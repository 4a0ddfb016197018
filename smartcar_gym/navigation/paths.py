"""Following a global path: the waypoint ahead of a robot and its way to go along the path.

``PathTracker`` gives the global path's next waypoint: the point ``lookahead_m`` along the path
beyond the robot's nearest point, the nearest point never going back. ``to_base_frame`` turns a
point into a robot's base_link frame. ``path_trackers.PathTrackers`` runs N at once (compiled
where numba is installed), for the BARN task and the DWA driver.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def to_base_frame(point: Sequence[float], x: float, y: float,
                  theta: float) -> tuple[float, float]:
    """``point`` (odom frame) in the base_link frame of the pose (x, y, theta)."""
    dx, dy = point[0] - x, point[1] - y
    c, s = math.cos(theta), math.sin(theta)
    return c * dx + s * dy, -s * dx + c * dy


class PathTracker:
    """The waypoint ``lookahead_m`` along a polyline ``path`` (M, 2) beyond the point of it
    nearest the robot, searched from the last one found up to ``window_m`` further on (the
    robot's progress along the path never goes back)."""

    def __init__(self, path: np.ndarray, lookahead_m: float, window_m: float = 1.0) -> None:
        self.path = np.asarray(path, dtype=float).reshape(-1, 2)
        if len(self.path) == 0:
            raise ValueError("a path needs at least one point")
        d = self.path[1:] - self.path[:-1]
        # np.linalg.norm(d, axis=1)'s bits: sqrt(dx * dx + dy * dy), a third of its time
        self.arc = np.zeros(len(self.path))
        np.cumsum(np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]), out=self.arc[1:])
        self.lookahead_m = lookahead_m
        self.window_m = window_m
        self.index = 0

    @property
    def length_m(self) -> float:
        return float(self.arc[-1])

    def waypoint(self, xy: np.ndarray) -> np.ndarray:
        """The next waypoint (x, y) for a robot at ``xy``; advances the nearest point."""
        self._advance(xy)
        return self.point_at(self.arc[self.index] + self.lookahead_m)

    def to_go(self, xy: np.ndarray) -> float:
        """How far a robot at ``xy`` is from the path's end along it: its distance to the
        nearest point (advanced as ``waypoint`` does) plus the path beyond that point."""
        d = self._advance(xy)
        return float(self.length_m - self.arc[self.index]) + d

    def _advance(self, xy: np.ndarray) -> float:
        """Move the nearest point on (within ``window_m``); the robot's distance to it."""
        end = int(np.searchsorted(self.arc, self.arc[self.index] + self.window_m, side="right"))
        d = np.linalg.norm(self.path[self.index:end] - np.asarray(xy, dtype=float), axis=1)
        nearest = int(np.argmin(d))
        self.index += nearest
        return float(d[nearest])

    def point_at(self, s: float) -> np.ndarray:
        """The point ``s`` metres along the path (clipped to its ends)."""
        s = min(max(s, 0.0), self.length_m)
        return np.array([np.interp(s, self.arc, self.path[:, 0]),
                         np.interp(s, self.arc, self.path[:, 1])])
