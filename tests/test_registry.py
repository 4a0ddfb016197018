"""Every registered id: registration, both checkers, determinism across processes, vector envs
and SB3's VecEnvs, rendering."""

from __future__ import annotations

import hashlib
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.envs.registration import registry
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env
from stable_baselines3.common.env_util import make_vec_env

import smartcar_gym
from smartcar_gym.envs.tasks.registry import ENTRY_POINT, VECTOR_ENTRIES, env_ids, task_of
from smartcar_gym.registration import ENV_IDS

N_STEPS = 30
SB3_GOAL_ENV_NOTE = "We detected your env to be a GoalEnv"  # printed, not warned


def _flat(obs) -> np.ndarray:
    """An observation (a Box's array, or a Dict's arrays by key) as one float32 array."""
    if isinstance(obs, dict):
        return np.concatenate([np.asarray(obs[k], dtype=np.float32).ravel() for k in sorted(obs)])
    return np.asarray(obs, dtype=np.float32).ravel()


def rollout_digest(env_id: str, seed: int, n_steps: int = N_STEPS) -> str:
    """sha256 of a seeded rollout's observations, rewards and ends (seeded random actions)."""
    env = gym.make(env_id)
    env.action_space.seed(seed)
    digest = hashlib.sha256()
    try:
        obs, _ = env.reset(seed=seed)
        digest.update(_flat(obs).tobytes())
        for _ in range(n_steps):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            digest.update(_flat(obs).tobytes() + np.float64(reward).tobytes()
                          + bytes([terminated, truncated]))
            if terminated or truncated:
                obs, _ = env.reset()
                digest.update(_flat(obs).tobytes())
    finally:
        env.close()
    return digest.hexdigest()


def test_env_ids_is_one_exported_tuple_of_every_registered_id():
    assert isinstance(ENV_IDS, tuple) and smartcar_gym.ENV_IDS is ENV_IDS
    assert ENV_IDS == ("SmartCar-v0", "SmartCarSim-v0", "SmartCarArrive-v0", "SmartCarNav-v0",
                       "SmartCarGoal-v0", "SmartCarBARN-v0")
    assert env_ids() == ENV_IDS
    ours = {spec.id for spec in registry.values()
            if str(spec.entry_point).startswith("smartcar_gym.")}
    assert ours == set(ENV_IDS)
    limits = {}
    for env_id in ENV_IDS:
        spec, task = registry[env_id], task_of(env_id)
        how = task.ids[env_id]
        assert (spec.entry_point, spec.vector_entry_point, spec.max_episode_steps,
                spec.reward_threshold, spec.kwargs) == (
            ENTRY_POINT, f"{VECTOR_ENTRIES}:{env_id}", how.max_episode_steps,
            how.reward_threshold, {"task": task.name, **how.kwargs})
        limits[env_id] = (task.name, spec.max_episode_steps, spec.reward_threshold)
    assert limits == {"SmartCar-v0": ("reach", 200, 15.0), "SmartCarSim-v0": ("reach", 200, 15.0),
                      "SmartCarArrive-v0": ("reach", 200, 15.0),
                      "SmartCarNav-v0": ("nav", 200, None), "SmartCarGoal-v0": ("goal", 100, None),
                      "SmartCarBARN-v0": ("barn", None, None)}


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_both_checkers_pass_without_warnings(env_id, capsys):
    env = gym.make(env_id)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            gym_check_env(env.unwrapped, skip_render_check=True)
            sb3_check_env(env.unwrapped, warn=True)
        assert [f"{w.category.__name__}: {w.message}" for w in caught] == []
        out = capsys.readouterr().out
        assert (SB3_GOAL_ENV_NOTE in out) == isinstance(env.observation_space, gym.spaces.Dict)
    finally:
        env.close()


def test_rollouts_are_bit_identical_across_processes():
    """Every id, seeded, in this process and in a fresh interpreter: the same digests."""
    here = {env_id: rollout_digest(env_id, 11) for env_id in ENV_IDS}
    script = (
        "import sys; sys.path.insert(0, sys.argv[1])\n"
        "from test_registry import rollout_digest\n"
        "from smartcar_gym.registration import ENV_IDS\n"
        "for env_id in ENV_IDS: print(env_id, rollout_digest(env_id, 11))\n"
    )
    out = subprocess.run([sys.executable, "-c", script, str(_tests_dir())], capture_output=True,
                         text=True, timeout=300, check=True)
    there = dict(line.split() for line in out.stdout.splitlines())
    assert there == here
    assert len(set(here.values())) == len(ENV_IDS)
    assert rollout_digest("SmartCarNav-v0", 12) != here["SmartCarNav-v0"]


def _tests_dir() -> str:
    from pathlib import Path

    return str(Path(__file__).resolve().parent)


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("mode", ["sync", "async"])
def test_gymnasium_vector_envs_step_and_autoreset(env_id, mode):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, max_episode_steps=8)
    try:
        envs.action_space.seed(0)
        obs, _ = envs.reset(seed=0)
        assert obs in envs.observation_space
        ends = 0
        for _ in range(20):
            obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())
            assert obs in envs.observation_space
            assert rewards.shape == (2,) and np.all(np.isfinite(rewards))
            ends += int((terminated | truncated).sum())
        assert ends >= 4  # both sub-envs went through at least two episodes
        assert infos["is_success"].dtype == bool
    finally:
        envs.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_subproc_vec_env(env_id):
    # fork: quick; tests/test_env_vector.py shows that spawned workers register the ids too
    venv = make_vec_env(env_id, n_envs=2, seed=0, env_kwargs={"max_episode_steps": 8},
                        vec_env_cls=_subproc(), vec_env_kwargs={"start_method": "fork"})
    try:
        venv.action_space.seed(0)
        obs = venv.reset()
        ends = 0
        for _ in range(20):
            actions = np.stack([venv.action_space.sample() for _ in range(2)])
            obs, rewards, dones, infos = venv.step(actions)
            assert np.all(np.isfinite(_flat(obs))) and rewards.shape == (2,)
            for i in np.flatnonzero(dones):
                ends += 1
                assert "terminal_observation" in infos[i]
        assert ends >= 4
        if env_id == "SmartCarGoal-v0":  # what HER calls on the workers
            goals = np.zeros((3, 2))
            assert venv.env_method("compute_reward", goals, goals, [{}] * 3,
                                   indices=[0])[0].tolist() == [0.0, 0.0, 0.0]
    finally:
        venv.close()


def _subproc():
    from stable_baselines3.common.vec_env import SubprocVecEnv

    return SubprocVecEnv


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_rgb_array_rendering(env_id):
    env = gym.make(env_id, render_mode="rgb_array", render_width=160, render_height=120)
    try:
        assert env.metadata["render_fps"] == 10
        env.reset(seed=0)
        first = env.render()
        assert first.shape == (120, 160, 3) and first.dtype == np.uint8
        assert first.std() > 10  # not a blank frame
        assert np.array_equal(first, env.render())
        for _ in range(5):
            env.step(np.array([1.0, 0.5], dtype=np.float32))
        assert not np.array_equal(first, env.render())
    finally:
        env.close()
