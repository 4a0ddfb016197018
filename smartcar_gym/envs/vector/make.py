"""The fastest faithful vector env of an id: numpy, batched on an engine, or a loop."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from smartcar_gym.envs.vector.batched import SmartCarBatchVectorEnv, id_kwargs
from smartcar_gym.envs.vector.common import CannotBatch
from smartcar_gym.envs.vector.kinematic import SmartCarSimVectorEnv, supports
from smartcar_gym.envs.vector.loop import SmartCarLoopVectorEnv


def make_vector_env(env_id: str, num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """The fastest faithful vector env of ``env_id`` for ``num_envs`` cars (every id's
    ``vector_entry_point``).

    An id registered in the kinematic mode (SmartCarSim-v0), reaching a goal:
    ``SmartCarSimVectorEnv`` (numpy, pybullet's float32 positions, whatever the engine); any
    id on a registered engine with a car batch (``sim.engines``: ``Engine.car_batch``), in the
    hardware mode, with nothing only a single env's world runs
    (``SmartCarBatchVectorEnv.why_not``): ``SmartCarBatchVectorEnv``; anything else,
    differential-drive robots on an engine whose batch runs skid-steer bases only
    (``batches_differential``) included: ``SmartCarLoopVectorEnv``. ``kwargs`` are the single
    env's, plus ``max_episode_steps``, ``autoreset_mode`` and ``num_threads``.
    """
    given = id_kwargs(env_id, kwargs)
    registered = gym.spec(env_id).kwargs
    if registered.get("controller_mode") == "sim" and given.get("controller_mode") == "sim" \
            and given.get("task") == "reach" and supports(given) is None:
        return SmartCarSimVectorEnv(num_envs=num_envs, env_id=env_id, **given)
    if SmartCarBatchVectorEnv.why_not(env_id, given) is None:
        try:
            return SmartCarBatchVectorEnv(env_id, num_envs=num_envs, **given)
        except CannotBatch:  # the robot's drive (differential): the loop runs it
            pass
    return SmartCarLoopVectorEnv(env_id, num_envs=num_envs, **kwargs)
