"""The BARN challenge's protocol scaled to the car, its score and its clock.

Pure arithmetic, no simulator. ``BarnProtocol`` scales the challenge (``worlds.barn``: a goal
10 m ahead, success within 1 m, 100 s at the Jackal's 2 m/s) by ``scale`` = the car's width /
the Jackal's, with time at this car's top speed. ``barn_score`` is the challenge's score of a
run. ``RunClock`` times a run as the challenge does (from when the robot has moved).
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
