"""``eval_freq`` and ``eval_episodes`` in the hyperparameters (a preset's own evaluation
schedule): the command line wins, then the hyperparameters, then 20,000 and 40; a value that
is not a whole number in range is one line naming the key."""

import pytest

from smartcar_gym.agents import cli_train, runs
from smartcar_gym.agents.hyperparams import HyperparamsError


def _config(*argv: str) -> dict:
    args = cli_train.build_parser().parse_args(["--timesteps", "1024", *argv])
    return runs.new_config(args, "test")


def test_the_command_line_then_the_hyperparameters_then_the_defaults():
    assert (_config()["eval_freq"], _config()["eval_episodes"]) == (20_000, 40)
    preset = _config("--hyperparams", "eval_freq=5000", "eval_episodes=100")
    assert (preset["eval_freq"], preset["eval_episodes"]) == (5000, 100)
    given = _config("--eval-freq", "0", "--eval-episodes", "3",
                    "--hyperparams", "eval_freq=5000", "eval_episodes=100")
    assert (given["eval_freq"], given["eval_episodes"]) == (0, 3)
    assert _config("--hyperparams", "eval_freq=0")["eval_freq"] == 0  # evaluations off


@pytest.mark.parametrize(("setting", "message"), [
    ("eval_freq=-1", "eval_freq must be a whole number >= 0, got -1"),
    ("eval_freq=2.5", "eval_freq must be a whole number >= 0, got 2.5"),
    ("eval_episodes=0", "eval_episodes must be a whole number >= 1, got 0"),
    ("eval_episodes=True", "eval_episodes must be a whole number >= 1, got True"),
    ("eval_episodes=[40]", r"eval_episodes must be a whole number >= 1, got \[40\]"),
])
def test_a_bad_setting_names_its_key(setting, message):
    with pytest.raises(HyperparamsError, match=message):
        _config("--hyperparams", setting)


def test_the_shipped_preset_sets_its_own_schedule():
    """The main job's preset: 100 episodes every 10,000 steps, beside the training."""
    config = _config("--env-kwargs", "engine=planar", "--vectorization", "batched")
    assert (config["n_envs"], config["hyperparams"]["n_steps"]) == (64, 32)
    assert (config["eval_freq"], config["eval_episodes"], config["eval_async"]) == (
        10_000, 100, True)
    assert config["eval_engine"] is None  # evaluated on planar, the training engine
