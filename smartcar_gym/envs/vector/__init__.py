"""Vector envs: many cars per process through Gymnasium's vector API.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)`` calls
the entry point of ``env_id`` here. SmartCarSim-v0 (kinematic, no engine) is batched in numpy
arrays (``SmartCarSimVectorEnv``); SmartCar-v0, SmartCarNav-v0 and SmartCarGoal-v0 on an
engine with a car batch (MuJoCo: worlds stepped in C; planar: arrays; any engine registered
with ``car_batch``) are ``SmartCarBatchVectorEnv``, one class given the id's task parts
(``randomize`` too on the Nav and BARN ids, whose cars are built by a single env); the
pybullet ids, and the options only a single env's world has (the GUI, ``randomize`` on the
others, ...), step N single envs in a loop (``SmartCarLoopVectorEnv``). All follow the same
conventions (docs/vector.md). The names of the batched classes before they were one
(``SmartCarMujocoVectorEnv``, ...) still make them (``aliases``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from smartcar_gym.envs.vector.aliases import (
    SmartCarGoalMujocoVectorEnv,
    SmartCarGoalPlanarVectorEnv,
    SmartCarMujocoVectorEnv,
    SmartCarNavMujocoVectorEnv,
    SmartCarNavPlanarVectorEnv,
    SmartCarPlanarVectorEnv,
)
from smartcar_gym.envs.vector.batched import SmartCarBatchVectorEnv
from smartcar_gym.envs.vector.common import CannotBatch
from smartcar_gym.envs.vector.kinematic import SmartCarSimVectorEnv, supports
from smartcar_gym.envs.vector.loop import SmartCarLoopVectorEnv

__all__ = ["SmartCarBatchVectorEnv", "SmartCarGoalMujocoVectorEnv",
           "SmartCarGoalPlanarVectorEnv", "SmartCarLoopVectorEnv", "SmartCarMujocoVectorEnv",
           "SmartCarNavMujocoVectorEnv", "SmartCarNavPlanarVectorEnv",
           "SmartCarPlanarVectorEnv", "SmartCarSimVectorEnv",
           "make_vector_env", "smartcar_arrive_v0", "smartcar_goal_v0", "smartcar_nav_v0",
           "smartcar_sim_v0", "smartcar_v0"]


def make_vector_env(env_id: str, num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """The fastest faithful vector env of ``env_id`` for ``num_envs`` cars.

    SmartCarSim-v0 in the kinematic mode: ``SmartCarSimVectorEnv`` (numpy); SmartCar-v0,
    SmartCarNav-v0 and SmartCarGoal-v0 on a registered engine with a car batch
    (``sim.engines``: ``Engine.car_batch``), in the hardware mode, with nothing only a single
    env's world runs (``SmartCarBatchVectorEnv.why_not``): ``SmartCarBatchVectorEnv``;
    anything else, differential-drive robots on an engine whose batch runs skid-steer bases
    only (``batches_differential``) included: ``SmartCarLoopVectorEnv``. ``kwargs`` are the
    single env's, plus ``max_episode_steps``, ``autoreset_mode`` and ``num_threads``.
    """
    if env_id == "SmartCarSim-v0" and supports(kwargs) is None \
            and kwargs.get("controller_mode", "sim") == "sim":
        return SmartCarSimVectorEnv(num_envs=num_envs, **kwargs)
    if SmartCarBatchVectorEnv.why_not(env_id, kwargs) is None:
        try:
            return SmartCarBatchVectorEnv(env_id, num_envs=num_envs, **kwargs)
        except CannotBatch:  # the robot's drive (differential): the loop runs it
            pass
    return SmartCarLoopVectorEnv(env_id, num_envs=num_envs, **kwargs)


def smartcar_v0(num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """SmartCar-v0's ``vector_entry_point`` (MuJoCo: batched in C; pybullet: a loop)."""
    return make_vector_env("SmartCar-v0", num_envs, **kwargs)


def smartcar_sim_v0(num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """SmartCarSim-v0's ``vector_entry_point`` (numpy arrays)."""
    return make_vector_env("SmartCarSim-v0", num_envs, **kwargs)


def smartcar_nav_v0(num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """SmartCarNav-v0's ``vector_entry_point`` (MuJoCo: batched in C; pybullet: a loop)."""
    return make_vector_env("SmartCarNav-v0", num_envs, **kwargs)


def smartcar_arrive_v0(num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """SmartCarArrive-v0's ``vector_entry_point`` (pybullet: a loop of single envs)."""
    return make_vector_env("SmartCarArrive-v0", num_envs, **kwargs)


def smartcar_goal_v0(num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """SmartCarGoal-v0's ``vector_entry_point`` (MuJoCo: batched in C; pybullet: a loop)."""
    return make_vector_env("SmartCarGoal-v0", num_envs, **kwargs)
