"""An engine as a plug-in: the planar engine registered again under another name.

Through the public API only (``smartcar_gym.sim.engines``): the copy, called ``flatland``,
is the planar engine's description (``Engine``) with a new name. Every registered env id
then runs on it: Gymnasium's ``check_env`` on one env, and a few steps of a vector env of two
(``gym.make_vec(..., vectorization_mode="vector_entry_point")``). Prints ``ok``.

    python examples/engine_plugin.py

docs/engines.md ("Writing an engine") shows how to write an engine of your own.
"""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env

import smartcar_gym  # noqa: F401 (registers the env ids)
from smartcar_gym.registration import ENV_IDS
from smartcar_gym.sim.engines import engine_names, get_engine, register_engine

NAME = "flatland"


def register() -> None:
    """``flatland``: the planar engine's description under another name (once)."""
    if NAME not in engine_names():
        register_engine(dataclasses.replace(get_engine("planar"), name=NAME,
                                            summary="the planar engine, registered again"))


def check(env_id: str, steps: int = 3) -> None:
    """``check_env`` on ``env_id`` with the engine, then ``steps`` steps of a vector env of 2."""
    env = gym.make(env_id, engine=NAME, render_mode="rgb_array")
    try:
        check_env(env.unwrapped)
    finally:
        env.close()
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        engine=NAME)
    try:
        envs.reset(seed=0)
        for _ in range(steps):
            envs.step(np.stack([envs.single_action_space.sample() for _ in range(2)]))
    finally:
        envs.close()


def main() -> None:
    register()
    with warnings.catch_warnings():
        # SmartCarSim-v0 steps no physics, and says so when given an engine
        warnings.filterwarnings("ignore", message=".*steps no physics")
        for env_id in ENV_IDS:
            check(env_id)
    print("ok")


if __name__ == "__main__":
    main()
