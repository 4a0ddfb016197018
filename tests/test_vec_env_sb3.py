"""The SB3 adapter of the vector envs, and smartcar-train --vectorization batched."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import yaml
from stable_baselines3.common.vec_env import DummyVecEnv

import smartcar_gym  # noqa: F401
from smartcar_gym.agents.env_factory import EnvSetupError
from smartcar_gym.agents.sb3_vec_env import GymVectorVecEnv
from smartcar_gym.agents.vec_envs import make_batched_vec_env


@pytest.mark.parametrize(("env_id", "n", "limit", "steps"),
                         [("SmartCarSim-v0", 4, 30, 70), ("SmartCar-v0", 2, 5, 12)])
def test_batched_vec_env_equals_sb3_dummy_vec_env_of_single_envs(env_id, n, limit, steps):
    batched = make_batched_vec_env(env_id, n, seed=3, env_kwargs={"max_episode_steps": limit})
    single = DummyVecEnv([lambda: gym.make(env_id, max_episode_steps=limit)] * n)
    single.seed(3)
    rng = np.random.default_rng(0)
    try:
        assert np.array_equal(batched.reset(), single.reset())
        ends = 0
        for _ in range(steps):
            actions = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
            obs, rewards, dones, infos = batched.step(actions)
            want_obs, want_rewards, want_dones, want_infos = single.step(actions)
            assert np.array_equal(obs, want_obs) and np.array_equal(rewards, want_rewards)
            assert np.array_equal(dones, want_dones)
            for i in np.flatnonzero(dones):
                ends += 1
                got, want = infos[i], want_infos[i]
                assert np.array_equal(got["terminal_observation"], want["terminal_observation"])
                assert got["is_success"] is want["is_success"]
                assert got["TimeLimit.truncated"] == want["TimeLimit.truncated"]
                assert got["episode"]["l"] == limit and "is_success" in got  # VecMonitor's
        assert ends >= 2 * n
    finally:
        batched.close()
        single.close()


def test_adapter_needs_same_step_autoreset():
    venv = gym.make_vec("SmartCarSim-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="SameStep"):
        GymVectorVecEnv(venv)


def test_bad_batched_env_is_a_setup_error():
    with pytest.raises(EnvSetupError, match="num_envs must be an integer >= 1"):
        make_batched_vec_env("SmartCarSim-v0", 0)


@pytest.mark.slow
def test_smartcar_train_batched_runs_and_records_it(tmp_path):
    from smartcar_gym.agents.cli_train import main

    run = tmp_path / "run"
    code = main(["--env", "SmartCarSim-v0", "--vectorization", "batched", "--n-envs", "8",
                 "--timesteps", "512", "--eval-freq", "512", "--eval-episodes", "4",
                 "--hyperparams", "n_steps=64", "batch_size=64", "--run-dir", str(run),
                 "--no-progress"])
    assert code == 0
    config = yaml.safe_load((run / "config.yaml").read_text())
    assert config["vectorization"] == "batched" and config["n_envs"] == 8
    assert config["hyperparams"]["n_steps"] == 64
    summary = json.loads((run / "summary.json").read_text())
    assert summary["num_timesteps"] == 512 and summary["final_eval"] is not None
    assert (run / "monitor" / "seg0_batched.monitor.csv").is_file()
