"""The cars of any smartcar vector env as a classical driver reads them: their public state and
their task, whichever vector env runs them.

A batched env (``SmartCarBatchVectorEnv``) has one state and one task over its cars; a loop of
single envs (``SmartCarLoopVectorEnv``, pybullet) one each. ``CarView`` shows both the same
way: ``state`` (every car's rows, ``envs.state.CarState``), ``per_car(name)`` (a task's
per-car attribute, one value a car), and the car's settings (robot, speeds, period, laser).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from smartcar_gym.envs.state import CarState


class CarView:
    """The cars of ``envs`` (a smartcar vector env, or a list of single envs)."""

    def __init__(self, envs: gym.vector.VectorEnv | list[gym.Env]) -> None:
        u = envs if isinstance(envs, list) else envs.unwrapped
        if isinstance(u, list) or not hasattr(u, "state"):
            singles = u if isinstance(u, list) else u.envs
            self._singles = [env.unwrapped for env in singles]
            self._batch = None
            first = self._singles[0]
        else:
            self._singles, self._batch = [], u
            first = u.settings
        #: the first car's single env: the settings every car shares
        self.settings = first
        #: the task the cars run (the first car's, for a loop): its settings
        self.task = first.task if self._batch is None else u.task

    @property
    def num(self) -> int:
        """How many cars."""
        return self._batch.num_envs if self._batch is not None else len(self._singles)

    @property
    def state(self) -> CarState:
        """Every car's state (a loop's: its envs' rows, copied)."""
        if self._batch is not None:
            return self._batch.state
        return CarState.stack([env.state for env in self._singles])

    def per_car(self, name: str) -> list[Any]:
        """The task's per-car attribute ``name`` (``global_paths``, ``map_poses``), a value
        a car."""
        if self._batch is not None:
            return list(getattr(self._batch.task, name))
        return [getattr(env.task, name)[0] for env in self._singles]

    def tasks(self) -> list[Any]:
        """Every task object that runs the cars (one for a batch)."""
        return [self._batch.task] if self._batch is not None else \
            [env.task for env in self._singles]
