"""The RLlib PPO recipe on a local 2-CPU Ray head, tiny budgets, hard timeouts.

Says nothing about learning or speed: one iteration of 100 steps checks the seams (the env
creator in the installed package, EnvRunners on the CPUs there are, success in the results,
checkpoints that restore).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ray.rllib", reason='RLlib is not installed: pip install "smartcar-gym[ray]"')
pytestmark = pytest.mark.xdist_group("ray")  # one Ray cluster at a time (pytest-xdist)

from smartcar_gym.scale import rllib  # noqa: E402
from smartcar_gym.scale.ray_session import ResourceError, ray_session  # noqa: E402
from smartcar_gym.scale.rllib_env import make_env  # noqa: E402

# Every episode ends at its first step with a success: goals 0.5-0.6 m away, 0.7 m tolerance.
EASY = {"goal_range": [0.5, 0.6], "goal_tolerance": 0.7}
TINY = {"train_batch_size": 100, "minibatch_size": 50, "num_epochs": 1,
        "evaluation_interval": 1, "evaluation_episodes": 2}


@pytest.fixture(scope="module")
def ray_head():
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")  # no token written under $HOME
    with ray_session(num_cpus=2, log_to_driver=False) as ray:  # smartcar-rllib's local head
        yield ray


def test_more_env_runners_than_cpus_is_refused_at_once(ray_head, hard_timeout):
    hard_timeout(30)
    config = rllib.ppo_config(num_env_runners=3, **TINY)
    # Ray 2.x would wait forever in build_algo(), without a word
    with pytest.raises(ResourceError, match=r"3 EnvRunner\(s\) .* need 3 CPUs at once, but the "
                                            r"Ray cluster has 2 .*num_env_runners"):
        rllib.build(config)
    rllib.check_resources(rllib.ppo_config(num_env_runners=2, **TINY))  # fits


def test_train_save_restore(ray_head, hard_timeout, tmp_path):
    hard_timeout(150)
    import torch
    from ray.rllib.core import DEFAULT_MODULE_ID
    from ray.rllib.core.rl_module.rl_module import RLModule

    ray_results = Path("~/ray_results").expanduser()
    before = set(ray_results.iterdir()) if ray_results.is_dir() else set()
    config = rllib.ppo_config(num_env_runners=2, env_kwargs=EASY, **TINY)
    rows = rllib.run(config, iterations=1, out=tmp_path / "run")
    # nothing left in the user's ~/ray_results (Ray's default place for an algorithm's logs)
    assert (set(ray_results.iterdir()) if ray_results.is_dir() else set()) == before
    assert len(rows) == 1 and rows[0]["iteration"] == 1
    assert rows[0]["env_steps"] >= 100
    # is_success reaches the results, in training (EnvRunners) and evaluation (driver)
    assert rows[0]["success_rate"] == 1.0 and rows[0]["eval_success_rate"] == 1.0
    assert json.loads((tmp_path / "run" / "progress.jsonl").read_text()) == rows[0]
    checkpoint = tmp_path / "run" / "checkpoint_000001"
    assert (checkpoint / "rllib_checkpoint.json").is_file()

    # the policy alone, without Ray, from the checkpoint
    module = RLModule.from_checkpoint(
        checkpoint / "learner_group" / "learner" / "rl_module" / DEFAULT_MODULE_ID)
    env = make_env({})
    try:
        obs, _ = env.reset(seed=0)
        out = module.forward_inference({"obs": torch.as_tensor(obs[None])})
        dist = module.get_inference_action_dist_cls().from_logits(out["action_dist_inputs"])
        action = dist.to_deterministic().sample()[0].numpy()
        assert action.shape == env.action_space.shape and np.all(np.isfinite(action))
    finally:
        env.close()

    # continue on other resources (no EnvRunner: all in the driver): the counter goes on
    again = rllib.ppo_config(num_env_runners=0, env_kwargs=EASY, **TINY)
    rows = rllib.run(again, iterations=1, out=tmp_path / "more", restore=checkpoint)
    assert rows[0]["iteration"] == 2 and rows[0]["env_steps"] >= 200
    assert (tmp_path / "more" / "checkpoint_000002").is_dir()


def test_command_line_errors(capsys):
    with pytest.raises(SystemExit) as exit_:
        rllib.main(["--out", "x", "--address", "auto", "--num-cpus", "2"])
    assert exit_.value.code == 2
    assert "--num-cpus is for a new local Ray instance" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        rllib.main(["--out", "x", "--restore", "nowhere"])
    assert exit_.value.code == 2
    assert "nowhere is not an RLlib checkpoint folder" in capsys.readouterr().err
