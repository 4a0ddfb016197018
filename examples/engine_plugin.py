"""An engine as a plug-in: the planar engine with a keyword of its own, under another name.

Through the public API only (``smartcar_gym.sim.engines``): ``flatland`` is the planar
engine's description (``Engine``) with a new name and one env keyword of its own,
``flatland_grip``: the tyres' grip, as a share of the planar fit's (its ``friction_scale``
times it), which the engine's simulator takes as the planar engine's parameters. Every
registered env id then runs on it with ``flatland_grip=0.8``: Gymnasium's ``check_env`` on one
env, and a few steps of a vector env of two (``gym.make_vec(...,
vectorization_mode="vector_entry_point")``). Prints ``ok``.

    python examples/engine_plugin.py

docs/engines.md ("Writing an engine") shows how to write an engine of your own.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env

import smartcar_gym  # noqa: F401 (registers the env ids)
from smartcar_gym.registration import ENV_IDS
from smartcar_gym.sim.engines import engine_names, get_engine, register_engine

NAME = "flatland"


KEYWORD = "flatland_grip"
GRIP = 0.8


def resolve_grip(value: Any, model: Any = None) -> Any:
    """``flatland_grip`` (None: 1, a number > 0) as the planar engine's parameters for the
    robot ``model``: its fit with the tyres' friction scaled by the grip."""
    grip = 1.0 if value is None else value
    if not (isinstance(grip, int | float) and grip > 0):
        raise ValueError(f"{KEYWORD} must be a number > 0, got {value!r}")
    fit = get_engine("planar").kwargs["planar_params"](None, model)
    return dataclasses.replace(fit, friction_scale=fit.friction_scale * grip)


def simulator(flatland_grip: Any = None, **options: Any) -> Any:
    """A planar world with the grip's parameters (``flatland_grip``: resolved already)."""
    params = flatland_grip if flatland_grip is not None else resolve_grip(None)
    return get_engine("planar").simulator(planar_params=params, **options)


def register() -> None:
    """``flatland``: the planar engine with its own keyword, under another name (once)."""
    if NAME not in engine_names():
        register_engine(dataclasses.replace(
            get_engine("planar"), name=NAME, simulator=simulator,
            kwargs={KEYWORD: resolve_grip},
            summary=f"the planar engine with {KEYWORD} (the tyres' grip)"))


def check(env_id: str, steps: int = 3) -> None:
    """``check_env`` on ``env_id`` with the engine, then ``steps`` steps of a vector env of 2."""
    env = gym.make(env_id, engine=NAME, render_mode="rgb_array", **{KEYWORD: GRIP})
    try:
        check_env(env.unwrapped)
    finally:
        env.close()
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        engine=NAME, **{KEYWORD: GRIP})
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
