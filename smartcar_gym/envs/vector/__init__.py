"""Vector envs: many cars per process through Gymnasium's vector API.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)`` calls
the entry point of ``env_id`` here. SmartCarSim-v0 (kinematic, no engine) is batched in numpy
arrays (``SmartCarSimVectorEnv``); SmartCar-v0, SmartCarNav-v0 and SmartCarGoal-v0 with
``engine="mujoco"`` step every car's MuJoCo world in C (``SmartCarMujocoVectorEnv``,
``SmartCarNavMujocoVectorEnv``, ``SmartCarGoalMujocoVectorEnv``); the pybullet ids, and the
options only a single env's world has (``randomize``, the GUI, ...), step N single envs in a
loop (``SmartCarLoopVectorEnv``). All follow the same conventions (docs/vector.md).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from smartcar_gym.envs.vector.common import CannotBatch
from smartcar_gym.envs.vector.goal_mujoco import SmartCarGoalMujocoVectorEnv
from smartcar_gym.envs.vector.kinematic import SmartCarSimVectorEnv, supports
from smartcar_gym.envs.vector.loop import SmartCarLoopVectorEnv
from smartcar_gym.envs.vector.mujoco import SmartCarMujocoVectorEnv
from smartcar_gym.envs.vector.mujoco import supports as mujoco_supports
from smartcar_gym.envs.vector.nav_mujoco import SmartCarNavMujocoVectorEnv
from smartcar_gym.envs.vector.nav_mujoco import supports as nav_mujoco_supports
from smartcar_gym.envs.vector.planar import (
    SmartCarGoalPlanarVectorEnv,
    SmartCarNavPlanarVectorEnv,
    SmartCarPlanarVectorEnv,
)
from smartcar_gym.envs.vector.planar import nav_supports as nav_planar_supports
from smartcar_gym.envs.vector.planar import supports as planar_supports

__all__ = ["SmartCarGoalMujocoVectorEnv", "SmartCarGoalPlanarVectorEnv", "SmartCarLoopVectorEnv",
           "SmartCarMujocoVectorEnv", "SmartCarNavMujocoVectorEnv", "SmartCarNavPlanarVectorEnv",
           "SmartCarPlanarVectorEnv",
           "SmartCarSimVectorEnv",
           "make_vector_env", "smartcar_arrive_v0", "smartcar_goal_v0", "smartcar_nav_v0",
           "smartcar_sim_v0", "smartcar_v0"]


def make_vector_env(env_id: str, num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """The fastest faithful vector env of ``env_id`` for ``num_envs`` cars.

    SmartCarSim-v0 in the kinematic mode: ``SmartCarSimVectorEnv`` (numpy); SmartCar-v0 with
    ``engine="mujoco"`` (hardware mode, no ``randomize``, no GUI): ``SmartCarMujocoVectorEnv``
    (MuJoCo in C per car); SmartCarNav-v0 with ``engine="mujoco"`` (the same, and no
    ``render_mode``): ``SmartCarNavMujocoVectorEnv``; SmartCarGoal-v0 with
    ``engine="mujoco"`` (as SmartCar-v0): ``SmartCarGoalMujocoVectorEnv``; anything else,
    differential-drive robots included (the batches run skid-steer bases):
    ``SmartCarLoopVectorEnv``. ``kwargs`` are the single
    env's, plus ``max_episode_steps`` and ``autoreset_mode``.
    """
    if env_id == "SmartCarSim-v0" and supports(kwargs) is None \
            and kwargs.get("controller_mode", "sim") == "sim":
        return SmartCarSimVectorEnv(num_envs=num_envs, **kwargs)
    batch = {"SmartCar-v0": ((SmartCarPlanarVectorEnv, planar_supports),
                             (SmartCarMujocoVectorEnv, mujoco_supports)),
             "SmartCarNav-v0": ((SmartCarNavPlanarVectorEnv, nav_planar_supports),
                                (SmartCarNavMujocoVectorEnv, nav_mujoco_supports)),
             "SmartCarGoal-v0": ((SmartCarGoalPlanarVectorEnv, planar_supports),
                                 (SmartCarGoalMujocoVectorEnv, mujoco_supports))}.get(env_id, ())
    for cls, supported in batch:
        if supported(kwargs) is None:
            try:
                return cls(num_envs=num_envs, **kwargs)
            except CannotBatch:  # the robot's drive (differential): the loop runs it
                break
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
