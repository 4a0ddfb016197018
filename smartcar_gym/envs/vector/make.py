"""The fastest faithful vector env of an id: numpy, batched on an engine, or a loop."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from smartcar_gym.envs.vector.batched import SmartCarBatchVectorEnv, id_kwargs
from smartcar_gym.envs.vector.common import CannotBatch, check_num_threads
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
    if _kinematic(env_id, given):
        check_num_threads(given.pop("num_threads", None))  # numpy arrays: no worker threads
        return SmartCarSimVectorEnv(num_envs=num_envs, env_id=env_id, **given)
    if SmartCarBatchVectorEnv.why_not(env_id, given) is None:
        try:
            return SmartCarBatchVectorEnv(env_id, num_envs=num_envs, **given)
        except CannotBatch:  # the robot's drive (differential): the loop runs it
            pass
    return SmartCarLoopVectorEnv(env_id, num_envs=num_envs, **kwargs)


def loop_reason(env_id: str, kwargs: dict[str, Any]) -> str | None:
    """Why ``make_vector_env`` runs ``env_id`` with the single env's ``kwargs`` as a loop of
    single envs (``SmartCarLoopVectorEnv``); None where it batches the cars (numpy or an
    engine's car batch). A robot that only the car batch's constructor refuses (``CannotBatch``)
    is not foreseen here."""
    given = id_kwargs(env_id, kwargs)
    return None if _kinematic(env_id, given) else SmartCarBatchVectorEnv.why_not(env_id, given)


def _kinematic(env_id: str, given: dict[str, Any]) -> bool:
    """Whether ``SmartCarSimVectorEnv`` runs ``env_id`` with ``given`` (its kwargs over the
    id's): an id registered in the kinematic mode and left in it, reaching a goal."""
    registered = gym.spec(env_id).kwargs
    return (registered.get("controller_mode") == "sim" and given.get("controller_mode") == "sim"
            and given.get("task") == "reach" and supports(given) is None)
