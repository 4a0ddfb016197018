"""The BARN task: the challenge's protocol scaled to the car, its score, and the path's waypoint.

Pure arithmetic, no simulator. ``BarnProtocol`` scales the challenge (``worlds.barn``: a goal
10 m ahead, success within 1 m, 100 s at the Jackal's 2 m/s) by ``scale`` = the car's width /
the Jackal's, with time at this car's top speed. ``barn_score`` is the challenge's score of a
run. ``RunClock`` times a run as the challenge does (from when the robot has moved).
``PathTracker`` gives the global path's next waypoint: the point ``lookahead_m`` along the path
beyond the robot's nearest point, the nearest point never going back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from smartcar_gym.worlds.barn import (
    GOAL_XY,
    JACKAL_TOP_SPEED_M_S,
    JACKAL_WIDTH_M,
    MOVED_M,
    START_XY,
    SUCCESS_RADIUS_M,
    TIMEOUT_S,
)

#: the shipped smartcar's width (m): its wheels' outer faces, 2 x (0.08 + 0.02 / 2)
SHIPPED_CAR_WIDTH_M = 0.18
SHIPPED_TOP_SPEED_M_S = 0.5  # SmartCar-v0's max_linear

SUCCESS, COLLISION, TIMEOUT, FAILURE = "success", "collision", "timeout", "failure"
#: a run's outcomes: the challenge's three, and ``failure`` (flipped over or left the arena)
OUTCOMES = (SUCCESS, COLLISION, TIMEOUT, FAILURE)


@dataclass(frozen=True)
class BarnProtocol:
    """The challenge's protocol for a car ``scale`` times the Jackal's width whose top speed is
    ``top_speed_m_s``: distances times ``scale``, times at ``top_speed_m_s``."""

    scale: float = SHIPPED_CAR_WIDTH_M / JACKAL_WIDTH_M
    top_speed_m_s: float = SHIPPED_TOP_SPEED_M_S

    def __post_init__(self) -> None:
        for name in ("scale", "top_speed_m_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"BARN {name} must be a number > 0, got {value!r}")

    @property
    def goal_distance_m(self) -> float:
        """How far ahead of the start the goal is (the challenge's 10 m, scaled)."""
        return self.scale * math.dist(START_XY, GOAL_XY)

    @property
    def success_radius_m(self) -> float:
        return self.scale * SUCCESS_RADIUS_M

    @property
    def moved_m(self) -> float:
        """How far the car moves before a run's clock starts."""
        return self.scale * MOVED_M

    @property
    def time_factor(self) -> float:
        """This car's time for a scaled distance over the Jackal's time for the original."""
        return self.scale * JACKAL_TOP_SPEED_M_S / self.top_speed_m_s

    @property
    def timeout_s(self) -> float:
        """The challenge's 100 s, for the scaled distance at this car's top speed."""
        return TIMEOUT_S * self.time_factor

    def timeout_steps(self, period_s: float) -> int:
        """Steps of ``period_s`` (the controller's) in the timeout, rounded up."""
        return math.ceil(self.timeout_s / period_s - 1e-9)

    def optimal_time_s(self, path_length_m: float) -> float:
        """OT: the (scaled) path length at the car's top speed."""
        return path_length_m / self.top_speed_m_s


def barn_score(success: bool, actual_time_s: float, optimal_time_s: float,
               floor: float = 2.0) -> float:
    """The challenge's score of a run: ``success * OT / clip(AT, floor * OT, 8 * OT)``; at most
    ``1 / floor`` (0.5; ``floor=4``: the metric before 2024, at most 0.25)."""
    if not success:
        return 0.0
    return optimal_time_s / min(max(actual_time_s, floor * optimal_time_s), 8.0 * optimal_time_s)


class RunClock:
    """A run's time as the challenge counts it: from when the car is ``moved_m`` from its
    start until now."""

    def __init__(self, start_xy: np.ndarray, moved_m: float) -> None:
        self.start = np.asarray(start_xy, dtype=float)
        self.moved_m = moved_m
        self.started_s: float | None = None

    def update(self, xy: np.ndarray, now_s: float) -> None:
        """Note the car at ``xy`` (ground truth) at simulated time ``now_s``."""
        if self.started_s is None and math.dist(xy, self.start) >= self.moved_m:
            self.started_s = now_s

    def elapsed_s(self, now_s: float) -> float:
        """AT: seconds since the car moved (0 if it never did)."""
        return 0.0 if self.started_s is None else now_s - self.started_s


class PathTracker:
    """The waypoint ``lookahead_m`` along a polyline ``path`` (M, 2) beyond the point of it
    nearest the robot, searched from the last one found up to ``window_m`` further on (the
    robot's progress along the path never goes back)."""

    def __init__(self, path: np.ndarray, lookahead_m: float, window_m: float = 1.0) -> None:
        self.path = np.asarray(path, dtype=float).reshape(-1, 2)
        if len(self.path) == 0:
            raise ValueError("a path needs at least one point")
        steps = np.linalg.norm(np.diff(self.path, axis=0), axis=1)
        self.arc = np.concatenate([[0.0], np.cumsum(steps)])
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
