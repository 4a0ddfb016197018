"""smartcar-gym: the ROS tutorial smartcar as a Gymnasium environment (pybullet + emulated ArbotiX).

``import smartcar_gym`` registers the environments::

    import gymnasium as gym
    import smartcar_gym  # noqa: F401
    env = gym.make("SmartCar-v0")

A trained policy (the ``train`` extra): ``smartcar_gym.policy.Policy.load("default").act(obs)``.
"""

from __future__ import annotations

from smartcar_gym.model import ModelError, RobotModel, load_model
from smartcar_gym.registration import ENV_IDS, register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["ENV_IDS", "ModelError", "RobotModel", "load_model", "register_envs", "__version__"]
