"""smartcar-train with rl-baselines3-zoo's run keys, and rl-baselines3-zoo with our files."""

import importlib.util
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml
from stable_baselines3 import PPO

from smartcar_gym.agents import cli_train
from smartcar_gym.agents.hyperparams import default_hyperparams_file

# A zoo file with only a `default` entry: every run key the zoo has, each with a visible effect.
ZOO_FILE = """\
default:
  n_timesteps: 1000000     # stopped at 64 steps by the callback
  n_envs: 2
  policy: MlpPolicy
  normalize: "dict(norm_obs=True, norm_reward=False)"
  n_steps: 64
  batch_size: 64
  n_epochs: 1
  policy_kwargs: "dict(net_arch=[16, 16])"
  env_kwargs: {goal_range: [2.0, 2.2], max_episode_steps: 64}
  env_wrapper:
    - gymnasium.wrappers.RescaleAction: {min_action: -2, max_action: 2}
  vec_env_wrapper: stable_baselines3.common.vec_env.VecCheckNan
  frame_stack: 3
  monitor_kwargs: {info_keywords: [distance]}
  callback:
    # one episode per env: both envs end theirs at step 32 (max_episode_steps from the command)
    - stable_baselines3.common.callbacks.StopTrainingOnMaxEpisodes: {max_episodes: 1}
"""


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:.*precision lowered:UserWarning")  # RescaleAction's bounds
def test_smartcar_train_applies_the_zoo_run_keys(tmp_path):
    path = tmp_path / "zoo.yaml"
    path.write_text(ZOO_FILE)
    run_dir = tmp_path / "run"
    assert cli_train.main([
        "--hyperparams-file", str(path), "--run-dir", str(run_dir), "--seed", "3",
        "--eval-freq", "32", "--eval-start", "0", "--eval-episodes", "2", "--no-progress",
        "--env-kwargs", "max_episode_steps=32",  # the command line wins over env_kwargs
    ]) == 0

    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert config["env_kwargs"] == {"goal_range": [2.0, 2.2], "max_episode_steps": 32}
    assert config["hyperparams"]["frame_stack"] == 3
    model = PPO.load(run_dir / "model.zip")
    assert model.num_timesteps == 64  # the callback stopped the run after 2 x 32 steps
    assert model.observation_space.shape == (3 * 21,)  # frame_stack
    assert model.action_space.high.tolist() == [2.0, 2.0]  # env_wrapper
    for rank in (0, 1):
        monitor = pd.read_csv(run_dir / "monitor" / f"seg0_{rank}.monitor.csv", skiprows=1)
        assert list(monitor.columns) == ["r", "l", "t", "is_success", "distance"]
        assert monitor["l"].tolist() == [32] and monitor["distance"].iloc[0] > 1.5
    evals = np.load(run_dir / "eval" / "evaluations.npz")
    assert evals["timesteps"].tolist() == [32, 64]  # the eval env is wrapped the same way
    assert evals["successes"].shape == (2, 2)


@pytest.mark.slow
def test_rl_zoo3_trains_with_the_shipped_file(tmp_path):
    # not imported here: importing rl_zoo3 replaces gymnasium's TimeLimit process-wide (its
    # gym_patches: no truncation when an episode also terminates at the limit)
    if importlib.util.find_spec("rl_zoo3") is None:
        pytest.skip("rl_zoo3 is in the test extra: pip install -e .[test]")
    conf = default_hyperparams_file("ppo")
    result = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "SmartCar-v0",
         "--gym-packages", "smartcar_gym", "-conf", str(conf), "-n", "128", "--seed", "0",
         "--eval-freq", "-1", "-f", str(tmp_path / "logs"),
         "-params", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1",
         "env_kwargs:dict(max_episode_steps=32)"],
        capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    run = tmp_path / "logs" / "ppo" / "SmartCar-v0_1"
    # the zoo pickles its schedules as rl_zoo3 functions: unpickling them would import rl_zoo3
    model = PPO.load(run / "SmartCar-v0.zip", custom_objects={
        "learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0})
    assert model.num_timesteps == 128 and model.observation_space.shape == (21,)
    assert (run / "SmartCar-v0" / "vecnormalize.pkl").is_file()  # the file says normalize
    config = (run / "SmartCar-v0" / "config.yml").read_text()
    assert "dict(info_keywords=('is_success',))" in config
    for rank in (0, 1):  # the zoo's Monitor files log is_success because the file says so
        monitor = pd.read_csv(run / f"{rank}.monitor.csv", skiprows=1)
        assert list(monitor.columns) == ["r", "l", "t", "is_success"]
        assert monitor["l"].tolist() == [32, 32]

