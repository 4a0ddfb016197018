"""Goal-conditioned reaching: reward, termination and truncation as functions of goals.

What Gymnasium-Robotics' ``GoalEnv`` and Stable-Baselines3's ``HerReplayBuffer`` expect: the
functions take the achieved and desired goals of one step (``(2,)``) or of a batch
(``(..., 2)``), so HER can recompute rewards for goals it substitutes. Goals are positions in
the ``odom`` frame: the achieved goal is where the robot's odometry says it is.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

REWARD_TYPES = ("sparse", "dense")
FLIPPED = "flipped"  # the info key that says the car is on its side or roof


def info_flags(info: Any, key: str, shape: tuple[int, ...]) -> np.ndarray:
    """``info[key]`` (False when absent) for one info dict or a batch of them, as ``shape``."""
    if info is None:
        return np.zeros(shape, dtype=bool)
    if isinstance(info, Mapping):
        return np.full(shape, bool(info.get(key, False)))
    flags = [bool(i.get(key, False)) if isinstance(i, Mapping) else False
             for i in np.asarray(info, dtype=object).reshape(-1)]
    return np.asarray(flags, dtype=bool).reshape(shape)


@dataclass(frozen=True)
class GoalConditionedTask:
    """Reach ``desired`` with ``achieved`` to within ``goal_tolerance_m`` (odom frame).

    ``reward_type`` "sparse": -1 per step until the goal is reached, 0 there; "dense": minus
    the distance (m). Reaching the goal terminates; leaving the arena (|x| or |y| of the
    achieved goal above ``arena_half_size_m``) or flipping over (``info["flipped"]``)
    truncates: the car cannot go on, but the reward depends on the goals alone.
    """

    goal_tolerance_m: float = 0.1
    arena_half_size_m: float = 2.5
    reward_type: str = "sparse"

    def __post_init__(self) -> None:
        if self.reward_type not in REWARD_TYPES:
            raise ValueError(f"reward_type must be one of {REWARD_TYPES}, got "
                             f"{self.reward_type!r}")

    @staticmethod
    def distance(achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """Euclidean distance (m) between ``(..., 2)`` goals."""
        return np.linalg.norm(np.asarray(achieved, dtype=np.float64)
                              - np.asarray(desired, dtype=np.float64), axis=-1)

    def is_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """True where the achieved goal is within the tolerance of the desired one."""
        return self.distance(achieved, desired) < self.goal_tolerance_m

    def compute_reward(self, achieved: np.ndarray, desired: np.ndarray, info: Any) -> np.ndarray:
        """-1 / 0 (sparse) or minus the distance (dense), per goal pair."""
        if self.reward_type == "sparse":
            return -(~self.is_success(achieved, desired)).astype(np.float64)
        return -self.distance(achieved, desired)

    def compute_terminated(self, achieved: np.ndarray, desired: np.ndarray,
                           info: Any) -> np.ndarray:
        """True where the goal is reached."""
        return self.is_success(achieved, desired)

    def compute_truncated(self, achieved: np.ndarray, desired: np.ndarray,
                          info: Any) -> np.ndarray:
        """True where the achieved goal left the arena or the car flipped over."""
        outside = np.any(np.abs(np.asarray(achieved)) > self.arena_half_size_m, axis=-1)
        return outside | info_flags(info, FLIPPED, np.shape(outside))

