"""Hyperparameter files (zoo format), command-line overrides and their translation to SB3."""

import pytest
import torch

from smartcar_gym.agents.hyperparams import (
    ALGOS,
    HyperparamsError,
    build_algo_kwargs,
    load_hyperparams,
    normalize_kwargs,
    parse_key_value,
    parse_key_values,
    parse_policy_kwargs,
    parse_value,
    run_int,
)


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarSim-v0"])
def test_shipped_files_have_an_entry_per_env_that_builds(algo, env_id):
    hp = load_hyperparams(algo, env_id)
    assert hp["policy"] == "MlpPolicy"
    assert hp["n_timesteps"] <= 300_000  # the budget: within 300k environment steps
    assert normalize_kwargs(hp["normalize"])["norm_obs"] is True
    kwargs = build_algo_kwargs(algo, hp, n_actions=2)
    assert "n_timesteps" not in kwargs and "normalize" not in kwargs
    assert isinstance(kwargs["policy_kwargs"]["net_arch"], list)


def test_ppo_defaults_are_the_documented_ones():
    hp = load_hyperparams("ppo", "SmartCar-v0")
    assert hp["normalize"] is True
    assert (hp["n_envs"], hp["n_steps"], hp["batch_size"]) == (8, 256, 256)
    assert (hp["n_epochs"], hp["gamma"], hp["gae_lambda"]) == (10, 0.98, 0.95)
    assert hp["learning_rate"] == "lin_1e-3"  # zoo's linear decay from 1e-3 to 0
    assert parse_policy_kwargs(hp["policy_kwargs"]) == {"net_arch": [64, 64], "log_std_init": -1.0}
    # PPO finishes whole rollouts of n_steps * n_envs = 2048 steps: 249,856 is 122 of them, so
    # a default run stops exactly there (a budget between two multiples would run past it)
    assert hp["n_timesteps"] == 249_856 == 122 * hp["n_steps"] * hp["n_envs"]


def test_missing_env_id_names_the_file_and_the_ids_it_has():
    with pytest.raises(HyperparamsError, match=r"ppo\.yaml.*no hyperparameters for env 'Nope-v0'"):
        load_hyperparams("ppo", "Nope-v0")
    with pytest.raises(HyperparamsError, match="unknown algorithm 'dqn'"):
        load_hyperparams("dqn", "SmartCar-v0")


@pytest.mark.parametrize(("text", "expected"), [
    ("3e-4", 3e-4),  # YAML 1.1 would read this as a string
    ("1e5", 100000.0),
    ("0.95", 0.95),
    ("256", 256),
    ("true", True),
    ("[64, 64]", [64, 64]),
    ("{norm_obs: true, norm_reward: false}", {"norm_obs": True, "norm_reward": False}),
    ("lin_3e-4", "lin_3e-4"),
    ("dict(net_arch=[64, 64])", "dict(net_arch=[64, 64])"),
    ("auto", "auto"),
    ("", ""),
])
def test_values_are_parsed_as_yaml(text, expected):
    assert parse_value(text) == expected


def test_key_value_pairs():
    assert parse_key_value("learning_rate=1e-3") == ("learning_rate", 1e-3)
    assert parse_key_value("policy_kwargs=dict(net_arch=[8])") == ("policy_kwargs",
                                                                   "dict(net_arch=[8])")
    assert parse_key_values(["a=1", "b=x=y", "a=2"]) == {"a": 2, "b": "x=y"}


@pytest.mark.parametrize("bad", ["learning_rate", "=3", "1abc=2", "bad key=1", ""])
def test_malformed_key_value_is_rejected_with_an_example(bad):
    with pytest.raises(HyperparamsError, match="expected key=value"):
        parse_key_value(bad)


def test_policy_kwargs_strings_and_dicts():
    assert parse_policy_kwargs("dict(net_arch=[64, 64], activation_fn=nn.Tanh)") == {
        "net_arch": [64, 64], "activation_fn": torch.nn.Tanh}
    assert parse_policy_kwargs("dict(net_arch=dict(pi=[32], vf=[32]), log_std_init=-1.0, "
                               "optimizer_class=th.optim.AdamW)") == {
        "net_arch": {"pi": [32], "vf": [32]}, "log_std_init": -1.0,
        "optimizer_class": torch.optim.AdamW}
    assert parse_policy_kwargs("{'net_arch': [8]}") == {"net_arch": [8]}
    assert parse_policy_kwargs({"net_arch": [8], "activation_fn": "nn.ReLU"}) == {
        "net_arch": [8], "activation_fn": torch.nn.ReLU}


@pytest.mark.parametrize("bad", [
    "__import__('os').system('true')", "dict(net_arch=open('x'))", "nn.functional.relu",
    "[64, 64]", "dict(net_arch=[64,",
])
def test_policy_kwargs_refuses_anything_but_literals(bad):
    with pytest.raises(HyperparamsError):
        parse_policy_kwargs(bad)


def test_normalize_forms():
    assert normalize_kwargs(False) is None
    assert normalize_kwargs(True) == {"norm_obs": True, "norm_reward": True}
    assert normalize_kwargs("{'norm_obs': True, 'norm_reward': False}") == {
        "norm_obs": True, "norm_reward": False}
    assert normalize_kwargs({"clip_obs": 5.0})["clip_obs"] == 5.0
    with pytest.raises(HyperparamsError, match="normalize must be"):
        normalize_kwargs("maybe")


def test_algo_kwargs_schedules_noise_and_train_freq():
    from stable_baselines3.common.noise import NormalActionNoise
    from stable_baselines3.common.utils import LinearSchedule

    ppo = build_algo_kwargs("ppo", {"learning_rate": "lin_1e-3", "n_envs": 2, "policy": "x"}, 2)
    assert isinstance(ppo["learning_rate"], LinearSchedule)
    assert ppo["learning_rate"](1.0) == pytest.approx(1e-3)
    assert ppo["learning_rate"](0.0) == pytest.approx(0.0)
    td3 = build_algo_kwargs("td3", {"noise_type": "normal", "noise_std": 0.2,
                                    "train_freq": [1, "episode"]}, 2)
    assert isinstance(td3["action_noise"], NormalActionNoise)
    assert td3["train_freq"] == (1, "episode")


def test_unknown_hyperparameter_lists_what_is_accepted():
    with pytest.raises(HyperparamsError, match=r"unknown hyperparameter\(s\) for ppo: n_step\b"):
        build_algo_kwargs("ppo", {"n_step": 5}, 2)
    with pytest.raises(HyperparamsError, match="learning_rate: expected a number"):
        build_algo_kwargs("sac", {"learning_rate": "fast"}, 2)


@pytest.mark.parametrize(("key", "hint"), [
    ("seed", "use --seed"), ("device", "use --device"), ("verbose", "progress bar"),
    ("tensorboard_log", "<run-dir>/tb"), ("_init_setup_model", "internal"),
])
def test_arguments_set_by_smartcar_train_are_refused(key, hint):
    message = rf"hyperparameter {key} cannot be set: .*{hint}"
    for algo in ALGOS:
        with pytest.raises(HyperparamsError, match=message):
            build_algo_kwargs(algo, {key: 1}, 2)
    with pytest.raises(HyperparamsError) as exc:
        build_algo_kwargs("ppo", {"n_step": 5}, 2)
    accepted = str(exc.value).split("accepts ")[1]
    assert "learning_rate" in accepted and key not in accepted


def test_run_integers():
    assert run_int({"n_envs": 4}, "n_envs") == 4
    assert run_int({"n_timesteps": 2e5}, "n_timesteps") == 200_000
    assert run_int({}, "n_envs") is None
    for bad in ("abc", 0, 1.5, True, [2]):
        with pytest.raises(HyperparamsError, match=r"n_envs must be a whole number >= 1"):
            run_int({"n_envs": bad}, "n_envs")


def test_the_main_jobs_planar_preset_is_the_documented_one():
    # the README's training command reads it (docs/planar.md, "Training on planar")
    hp = load_hyperparams("ppo", "SmartCar-v0-batched-planar")
    assert (hp["n_envs"], hp["n_steps"], hp["batch_size"]) == (64, 32, 256)
    assert (hp["n_epochs"], hp["learning_rate"], hp["gamma"]) == (5, "lin_1.5e-3", 0.98)
    assert hp["n_timesteps"] == 262_144 == 128 * hp["n_steps"] * hp["n_envs"]
    assert (hp["eval_freq"], hp["eval_episodes"], hp["eval_async"]) == (10_000, 100, True)
