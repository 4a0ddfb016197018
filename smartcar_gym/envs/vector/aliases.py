"""The batched envs' names from before they were one class (docs/vector.md names them).

Each is a function that makes ``SmartCarBatchVectorEnv`` for its id on its engine, with the
old class's keywords (``num_envs``, ``max_episode_steps``, ``autoreset_mode``,
``num_threads``, the single env's kwargs) and errors (they name it). Kept for existing code;
new code makes ``SmartCarBatchVectorEnv(env_id, engine=...)`` or calls ``gym.make_vec``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from gymnasium.vector import AutoresetMode

from smartcar_gym.envs.vector.batched import SmartCarBatchVectorEnv

Maker = Callable[..., SmartCarBatchVectorEnv]


def _alias(name: str, env_id: str, engine: str) -> Maker:
    def make(num_envs: int = 1, max_episode_steps: int | None = None,
             autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
             num_threads: int | None = None, **kwargs: Any) -> SmartCarBatchVectorEnv:
        kwargs.setdefault("engine", engine)
        return SmartCarBatchVectorEnv(env_id, num_envs, max_episode_steps, autoreset_mode,
                                      num_threads, label=name, **kwargs)

    make.__name__ = make.__qualname__ = name
    make.__doc__ = (f"``SmartCarBatchVectorEnv({env_id!r}, engine={engine!r})`` (the name of "
                    "its class before the batched envs were one).")
    return make


SmartCarMujocoVectorEnv = _alias("SmartCarMujocoVectorEnv", "SmartCar-v0", "mujoco")
SmartCarNavMujocoVectorEnv = _alias("SmartCarNavMujocoVectorEnv", "SmartCarNav-v0", "mujoco")
SmartCarGoalMujocoVectorEnv = _alias("SmartCarGoalMujocoVectorEnv", "SmartCarGoal-v0", "mujoco")
SmartCarPlanarVectorEnv = _alias("SmartCarPlanarVectorEnv", "SmartCar-v0", "planar")
SmartCarNavPlanarVectorEnv = _alias("SmartCarNavPlanarVectorEnv", "SmartCarNav-v0", "planar")
SmartCarGoalPlanarVectorEnv = _alias("SmartCarGoalPlanarVectorEnv", "SmartCarGoal-v0", "planar")
