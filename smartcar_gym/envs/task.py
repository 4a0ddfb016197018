"""Goal reaching: goal sampling, success and reward as pure functions of arrays.

The functions take ``(..., 2)`` positions, so they work on one state or a batch of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GoalReachingTask:
    """Drive base_link to within ``goal_tolerance_m`` of a goal on the ground.

    Reward per step: ``progress_weight`` x (metres the robot got closer to the goal)
    - ``time_cost`` - ``action_cost`` x |action|^2, plus ``success_bonus`` on reaching the goal
    and minus ``failure_penalty`` on flipping over or leaving the arena.
    """

    goal_range_m: tuple[float, float] = (0.5, 1.5)
    goal_tolerance_m: float = 0.1
    arena_half_size_m: float = 2.5
    progress_weight: float = 10.0
    success_bonus: float = 10.0
    failure_penalty: float = 10.0
    time_cost: float = 0.01
    action_cost: float = 0.01

    def __post_init__(self) -> None:
        lo, hi = self.goal_range_m
        if not (0.0 <= lo <= hi and math.isfinite(hi)):
            raise ValueError(
                "goal_range must be (min, max) metres with 0 <= min <= max, "
                f"got {self.goal_range_m}"
            )
        if not self.goal_tolerance_m > 0:
            raise ValueError(f"goal_tolerance must be > 0 m, got {self.goal_tolerance_m}")
        if not hi < self.arena_half_size_m:
            raise ValueError(
                f"goal_range max ({hi} m) must lie inside the arena (half size "
                f"{self.arena_half_size_m} m): raise arena_size or lower goal_range"
            )

    def sample_goal(self, rng: np.random.Generator, origin: np.ndarray) -> np.ndarray:
        """A goal at a uniform distance in ``goal_range_m``, uniform bearing, from ``origin``."""
        distance = rng.uniform(*self.goal_range_m)
        bearing = rng.uniform(-math.pi, math.pi)
        return np.asarray(origin, dtype=float) + distance * np.array(
            [math.cos(bearing), math.sin(bearing)]
        )

    @staticmethod
    def distance(position: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Euclidean distance (m) between ``(..., 2)`` positions and goals."""
        return np.linalg.norm(np.asarray(position) - np.asarray(goal), axis=-1)

    def is_success(self, distance: np.ndarray) -> np.ndarray:
        """True where the distance to the goal is under the tolerance."""
        return np.asarray(distance) < self.goal_tolerance_m

    def is_outside(self, position: np.ndarray) -> np.ndarray:
        """True where a ``(..., 2)`` position has left the square arena."""
        return np.any(np.abs(np.asarray(position)) > self.arena_half_size_m, axis=-1)

    def reward(
        self,
        previous_distance: np.ndarray,
        distance: np.ndarray,
        action: np.ndarray,
        success: np.ndarray,
        failure: np.ndarray,
    ) -> np.ndarray:
        """Dense reward: progress, minus time and action costs, plus success/failure terms."""
        action = np.asarray(action, dtype=float)
        return (
            self.progress_weight * (np.asarray(previous_distance) - np.asarray(distance))
            - self.time_cost
            - self.action_cost * np.sum(action * action, axis=-1)
            + self.success_bonus * np.asarray(success, dtype=float)
            - self.failure_penalty * np.asarray(failure, dtype=float)
        )
