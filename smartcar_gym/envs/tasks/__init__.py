"""Tasks: goals, success, failure and reward as pure functions of arrays."""

from smartcar_gym.envs.tasks.nav import NavigationTask
from smartcar_gym.envs.tasks.obstacles import Obstacle, ObstacleField, read_layout
from smartcar_gym.envs.tasks.reach import GoalReachingTask, Outcome

__all__ = ["GoalReachingTask", "NavigationTask", "Obstacle", "ObstacleField", "Outcome",
           "read_layout"]
