"""Navigation: reach a goal among obstacles without touching them.

``NavigationTask`` is goal reaching (``GoalReachingTask``: goal sampling, success, leaving the
arena, flipping, the progress reward) plus a collision term: touching an obstacle costs
``collision_penalty`` and ends the episode. Where the obstacles stand is an ``ObstacleField``'s
business (``obstacles.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smartcar_gym.envs.tasks.reach import GoalReachingTask


@dataclass(frozen=True)
class NavigationTask(GoalReachingTask):
    """Goal reaching in which a collision is a failure that costs ``collision_penalty``, and
    coming within ``proximity_m`` of an obstacle costs up to ``proximity_penalty`` per step."""

    collision_penalty: float = 10.0
    proximity_penalty: float = 0.0
    proximity_m: float = 0.3

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("collision_penalty", "proximity_penalty"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be a number >= 0, got {getattr(self, name)!r}")
        if not self.proximity_m > 0:
            raise ValueError(f"proximity_m must be a positive number, got {self.proximity_m!r}")

    def collision_reward(self, collision: np.ndarray) -> np.ndarray:
        """The collision term of the reward: ``-collision_penalty`` where ``collision``."""
        return -self.collision_penalty * np.asarray(collision, dtype=float)

    def proximity_reward(self, clearance: np.ndarray) -> np.ndarray:
        """Per step: ``-proximity_penalty`` times how far (as a fraction of ``proximity_m``)
        the car is inside ``proximity_m`` of the nearest obstacle (0 beyond it)."""
        inside = (self.proximity_m - np.asarray(clearance, dtype=float)) / self.proximity_m
        return -self.proximity_penalty * np.clip(inside, 0.0, 1.0)
