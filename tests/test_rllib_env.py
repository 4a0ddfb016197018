"""The env creator RLlib's EnvRunners import (no Ray needed to make envs with it)."""

from __future__ import annotations

import numpy as np
import pytest

from smartcar_gym.scale.rllib_env import ENV_ID_KEY, make_env


def test_creator_makes_the_env_from_rllibs_env_config():
    env = make_env({ENV_ID_KEY: "SmartCarSim-v0", "goal_tolerance": 0.3})
    try:
        assert env.spec.id == "SmartCarSim-v0" and env.spec.max_episode_steps == 200
        assert env.unwrapped.controller_mode == "sim"
    finally:
        env.close()
    env = make_env(None)
    try:
        assert env.spec.id == "SmartCar-v0"
    finally:
        env.close()


def test_bad_env_config_fails_with_the_envs_message():
    with pytest.raises(ValueError, match="goal_tolerance"):
        make_env({"goal_tolerance": -1.0})


def test_two_envs_in_one_process_are_two_worlds():
    # num_envs_per_env_runner > 1 puts several envs in one EnvRunner: each needs its own
    # physics client, or a reset of one would reset the other and their steps would mix.
    a, b = make_env({}), make_env({})
    try:
        actions = [np.array([0.8, 0.3], dtype=np.float32)] * 25
        obs_a = [a.reset(seed=3)[0]]
        obs_b = [b.reset(seed=3)[0]]
        for action in actions:
            obs_a.append(a.step(action)[0])
        for action in actions:  # b starts after a has moved: a shared world would show it
            obs_b.append(b.step(action)[0])
        np.testing.assert_array_equal(np.array(obs_a), np.array(obs_b))
        assert not np.allclose(obs_a[0], obs_a[-1])  # the car moved
    finally:
        a.close()
        b.close()
