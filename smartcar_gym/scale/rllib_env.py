"""The smartcar env for RLlib: a creator every EnvRunner imports from the installed package.

RLlib builds the envs inside its EnvRunner processes, possibly on other machines. Gymnasium's
registry lives in one process, and a creator defined in a script or a test file cannot be
imported there, so the creator lives here, registered in Ray's own registry (which reaches
every worker) under ``ENV_NAME``. Each env it makes owns its own pybullet DIRECT client
(``smartcar_gym.sim`` never uses pybullet's global client), so several envs in one EnvRunner
(``num_envs_per_env_runner``) do not share a physics world.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

ENV_NAME = "SmartCar-v0"  # the name in Ray's registry (see register)
ENV_ID_KEY = "env_id"  # env_config key choosing the gymnasium id (default SmartCar-v0)


def make_env(env_config: Mapping[str, Any] | None = None) -> gym.Env:
    """A smartcar env from RLlib's ``env_config``: ``gym.make(env_config["env_id"], **rest)``.

    Runs in each EnvRunner; importing ``smartcar_gym`` there registers the gymnasium ids.
    """
    import smartcar_gym  # noqa: F401  (registers SmartCar-v0 in this process)

    kwargs = dict(env_config or {})  # an EnvContext is a dict of the user's keys
    env_id = kwargs.pop(ENV_ID_KEY, "SmartCar-v0")
    return gym.make(env_id, **kwargs)


def register() -> str:
    """Register ``make_env`` in Ray's registry under ``ENV_NAME`` (call it in the driver
    before building, and again in a new process before restoring); returns the name."""
    from ray.tune.registry import register_env

    register_env(ENV_NAME, make_env)
    return ENV_NAME

