"""Vectorised use: gymnasium's make_vec (sync, async) and SB3's SubprocVecEnv (fork, spawn)."""

from __future__ import annotations

import multiprocessing

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import SubprocVecEnv

import smartcar_gym  # noqa: F401

N_STEPS = 200
EPISODE = 40  # short episodes, so 200 steps cross several autoresets


def _is_reset_observation(obs: np.ndarray) -> bool:
    """Odometry at the origin heading +x, zero twist, no previous action."""
    return bool(np.array_equal(obs[0:6], [0, 0, 1, 0, 0, 0]) and np.array_equal(obs[17:19], [0, 0]))


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec_runs_and_autoresets(mode):
    envs = gym.make_vec(
        "SmartCar-v0", num_envs=2, vectorization_mode=mode, max_episode_steps=EPISODE
    )
    try:
        assert envs.num_envs == 2
        assert envs.single_action_space == gym.spaces.Box(-1, 1, (2,), np.float32)
        envs.action_space.seed(0)
        obs, infos = envs.reset(seed=0)
        assert obs.shape == (2, 21) and obs.dtype == np.float32
        assert not np.array_equal(obs[0], obs[1])  # seeds 0 and 1: different goals
        ends = resets_seen = 0
        done = np.zeros(2, dtype=bool)
        for _ in range(N_STEPS):
            obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
            assert obs in envs.observation_space
            assert rewards.shape == (2,) and np.all(np.isfinite(rewards))
            for i in np.flatnonzero(done):  # next-step autoreset: this step was a reset
                assert _is_reset_observation(obs[i]) and rewards[i] == 0
                resets_seen += 1
            done = terminated | truncated
            ends += int(done.sum())
            if done.any():
                assert infos["_is_success"][done].all()
                assert infos["is_success"].dtype == bool
        assert ends >= 2 * (N_STEPS // EPISODE) - 2  # every sub-env lived several episodes
        assert resets_seen >= ends - 2
    finally:
        envs.close()


@pytest.mark.parametrize("start_method", ["fork", "spawn"])
def test_sb3_subproc_vec_env(start_method):
    if start_method not in multiprocessing.get_all_start_methods():
        pytest.skip(f"{start_method} is not available here")
    # a spawned worker re-imports nothing of this test process: the id's module prefix
    # makes gymnasium import smartcar_gym (and register it) inside the worker
    env_id = "smartcar_gym:SmartCar-v0" if start_method == "spawn" else "SmartCar-v0"
    venv = make_vec_env(
        env_id, n_envs=2, seed=0, env_kwargs={"max_episode_steps": EPISODE},
        vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": start_method},
    )
    try:
        venv.action_space.seed(0)
        obs = venv.reset()
        assert obs.shape == (2, 21)
        ends = 0
        for _ in range(N_STEPS):
            actions = np.stack([venv.action_space.sample() for _ in range(2)])
            obs, rewards, dones, infos = venv.step(actions)
            assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rewards))
            for i in np.flatnonzero(dones):
                ends += 1
                assert isinstance(infos[i]["is_success"], bool)
                assert infos[i]["terminal_observation"].shape == (21,)
                assert _is_reset_observation(obs[i])  # SB3 resets at once
        assert ends >= 2 * (N_STEPS // EPISODE) - 2
    finally:
        venv.close()
