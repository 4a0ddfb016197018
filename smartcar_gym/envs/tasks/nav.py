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
    """Goal reaching in which a collision is a failure that costs ``collision_penalty``."""

    collision_penalty: float = 10.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.collision_penalty >= 0:
            raise ValueError(f"collision_penalty must be a number >= 0, got "
                             f"{self.collision_penalty!r}")

    def collision_reward(self, collision: np.ndarray) -> np.ndarray:
        """The collision term of the reward: ``-collision_penalty`` where ``collision``."""
        return -self.collision_penalty * np.asarray(collision, dtype=float)
