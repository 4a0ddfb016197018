"""SAC + HER on SmartCarGoal-v0 through smartcar-train (the shipped sac.yaml), and evaluating
Dict-observation policies with smartcar-eval."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from smartcar_gym.agents import cli_eval, cli_train
from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.hyperparams import build_algo_kwargs, load_hyperparams, normalize_kwargs
from smartcar_gym.agents.models import load_model
from smartcar_gym.agents.random_policy import RandomPolicy

FAST = ["max_episode_steps=20", "controller_mode=sim"]


class DriveToGoal:
    """A scripted Dict-observation policy: turn towards the desired goal, then drive."""

    def predict(self, obs, deterministic=True):
        observation = np.atleast_2d(obs["observation"])
        delta = np.atleast_2d(obs["desired_goal"]) - np.atleast_2d(obs["achieved_goal"])
        yaw = np.arctan2(observation[:, 3], observation[:, 2])
        bearing = np.angle(np.exp(1j * (np.arctan2(delta[:, 1], delta[:, 0]) - yaw)))
        v = np.clip(2.0 * np.linalg.norm(delta, axis=1), 0, 1) * (np.abs(bearing) < 0.6)
        return np.stack([v, np.clip(2.0 * bearing, -1, 1)], axis=1).astype(np.float32), None


def test_shipped_sac_entry_uses_her_and_a_multi_input_policy():
    from stable_baselines3 import HerReplayBuffer

    hp = load_hyperparams("sac", "SmartCarGoal-v0")
    assert hp["policy"] == "MultiInputPolicy" and hp["n_envs"] == 1
    kwargs = build_algo_kwargs("sac", hp, n_actions=2)
    assert kwargs["replay_buffer_class"] is HerReplayBuffer
    assert kwargs["replay_buffer_kwargs"] == {"goal_selection_strategy": "future",
                                              "n_sampled_goal": 4}
    assert normalize_kwargs(hp["normalize"]) == {"norm_obs": True, "norm_reward": False}


@pytest.fixture(scope="module")
def her_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("goal") / "sac"
    argv = ["--algo", "sac", "--env", "SmartCarGoal-v0", "--timesteps", "300", "--run-dir",
            str(run_dir), "--eval-freq", "300", "--eval-episodes", "2", "--no-progress",
            "--env-kwargs", *FAST, "--hyperparams", "buffer_size=2000", "learning_starts=100",
            "batch_size=32"]
    assert cli_train.main(argv) == 0
    return run_dir


@pytest.mark.slow
def test_smartcar_train_runs_sac_with_her(her_run):
    config = yaml.safe_load((her_run / "config.yaml").read_text())
    assert config["hyperparams"]["replay_buffer_class"] == "HerReplayBuffer"
    summary = json.loads((her_run / "summary.json").read_text())
    assert summary["num_timesteps"] == 300 and summary["final_eval"]["timesteps"] == 300
    model = load_model(her_run / "model.zip", "sac")
    assert model.replay_buffer is not None and model.replay_buffer.buffer_size == 1
    assert set(model.observation_space.spaces) == {"observation", "achieved_goal",
                                                   "desired_goal"}


@pytest.mark.slow
def test_smartcar_eval_of_a_her_model(her_run, tmp_path, capsys):
    out = tmp_path / "eval.json"
    argv = ["--model", str(her_run / "model.zip"), "--episodes", "3", "--n-envs", "2",
            "--json", str(out), "--no-progress"]
    assert cli_eval.main(argv) == 0
    assert "success rate" in capsys.readouterr().out
    report = json.loads(out.read_text())
    assert report["episodes"] == 3 and report["env"] == "SmartCarGoal-v0"
    assert len(report["episode_records"]) == 3


@pytest.mark.slow
def test_dict_policies_give_the_same_records_with_any_number_of_envs():
    kwargs = dict(env_id="SmartCarGoal-v0", n_episodes=4, seed=5,
                  env_kwargs={"controller_mode": "sim", "max_episode_steps": 60})
    one = [r.to_dict() for r in evaluate_policy_episodes(DriveToGoal(), **kwargs)]
    two = [r.to_dict() for r in evaluate_policy_episodes(DriveToGoal(), n_envs=2, **kwargs)]
    assert one == two
    assert sum(r["success"] for r in one) >= 3  # the scripted policy reaches the goals
    random = evaluate_policy_episodes(RandomPolicy(0), **{**kwargs, "n_episodes": 2})
    assert [r.length for r in random] == [60, 60]
