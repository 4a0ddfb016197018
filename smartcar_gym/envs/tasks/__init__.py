"""Tasks: goals, success, failure and reward as pure functions of arrays."""

from smartcar_gym.envs.tasks.reach import GoalReachingTask, Outcome

__all__ = ["GoalReachingTask", "Outcome"]
