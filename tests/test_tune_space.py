"""smartcar-tune search spaces: parsing, checks before Ray starts, the list of trials."""

from __future__ import annotations

import math

import pytest
import yaml

from smartcar_gym.agents.hyperparams import load_hyperparams
from smartcar_gym.scale.space import (
    Dimension,
    SpaceError,
    apply_overrides,
    build_sweep,
    env_kwargs_samples,
    fit_grace_period,
    load_space,
    parse_dimension,
    preset_cpus,
    shipped_space_file,
)


def sweep_of(**data):
    return build_sweep(data, "space.yaml")


def test_shipped_space_is_valid_and_lists_its_trials():
    data, path = load_space()
    assert path == shipped_space_file()
    sweep = build_sweep(data, path, path.parent)
    assert sweep.algo == "ppo" and sweep.timesteps == 102400
    assert set(sweep.dimensions()) == {"learning_rate", "n_epochs", "seed"}
    trials = sweep.trial_values()
    # n_epochs grid (2) x seeds (2), one sample
    assert len(trials) == 4
    assert [t["n_epochs"] for t in trials] == [10, 10, 20, 20]
    assert [t["seed"] for t in trials] == [0, 1, 0, 1]
    # ppo.yaml's values under the space's overrides; n_timesteps is the space's timesteps
    config = sweep.trial_config(trials[0])
    base = load_hyperparams("ppo", "SmartCar-v0")
    assert config["hyperparams"]["n_envs"] == 1 and config["hyperparams"]["n_steps"] == 2048
    assert config["hyperparams"]["gae_lambda"] == base["gae_lambda"]
    assert "n_timesteps" not in config["hyperparams"] and config["timesteps"] == 102400
    # ASHA decides at evaluations: its first rung is a multiple of them
    assert sweep.early_stopping["grace_period"] % sweep.eval_freq == 0


@pytest.mark.parametrize(("engine", "n_envs", "n_steps", "timesteps", "cpus"), [
    ("planar", 64, 32, 262144, 2), ("mujoco", 16, 128, 249856, 1)])
def test_the_shipped_batched_space_is_smartcar_train_s_batched_preset(engine, n_envs, n_steps,
                                                                       timesteps, cpus):
    """``smartcar-tune --engine E --vectorization batched``: the entry ``smartcar-train
    --engine E --vectorization batched`` takes, with the space's values on top; a trial asks
    for the CPUs it uses (planar: its process and the eval_async one)."""
    data, path = load_space(shipped_space_file(vectorization="batched"))
    assert path.name == "tune_ppo_batched.yaml"
    data = apply_overrides(data, env_kwargs={"engine": engine})
    sweep = build_sweep(data, path, path.parent)
    preset = load_hyperparams("ppo", "SmartCar-v0", variant=(f"batched-{engine}", "batched"))
    assert sweep.vectorization == "batched" and sweep.timesteps == timesteps == preset.pop(
        "n_timesteps")
    assert sweep.cpus_per_trial == cpus
    assert set(sweep.dimensions()) == {"learning_rate", "n_epochs", "seed"}
    assert len(sweep.trial_values()) == 16
    config = sweep.trial_config(sweep.trial_values()[0])
    assert config["vectorization"] == "batched" and config["env_kwargs"] == {"engine": engine}
    searched = ("learning_rate", "n_epochs")
    assert {k: v for k, v in config["hyperparams"].items() if k not in searched} == {
        k: v for k, v in preset.items() if k not in searched}
    assert (config["hyperparams"]["n_envs"], config["hyperparams"]["n_steps"]) == (n_envs, n_steps)


def test_a_trial_s_cpus_default_to_what_its_run_uses():
    assert preset_cpus("subproc", {"eval_async": True}) == 1  # n_envs follows cpus_per_trial
    assert preset_cpus("batched", {"eval_async": True}) == 2
    assert preset_cpus("batched", {"eval_async": False}) == 1
    sweep = sweep_of(vectorization="batched", env_kwargs={"engine": "planar"},
                     hyperparams={"eval_async": False})
    assert sweep.cpus_per_trial == 1 and sweep.hyperparams["n_envs"] == 64
    assert sweep_of(vectorization="batched", env_kwargs={"engine": "planar"},
                    cpus_per_trial=3).cpus_per_trial == 3


def test_seeds_of_a_configuration_share_its_random_draws():
    sweep = sweep_of(hyperparams={"learning_rate": {"loguniform": [1e-4, 1e-3]},
                                  "n_epochs": {"choice": [5, 10, 20]}},
                     seed={"grid": [3, 4, 5]}, num_samples=4)
    trials = sweep.trial_values()
    assert len(trials) == 12
    for i in range(0, 12, 3):
        group = trials[i:i + 3]
        assert [t["seed"] for t in group] == [3, 4, 5]
        assert len({(t["learning_rate"], t["n_epochs"]) for t in group}) == 1
    rates = [t["learning_rate"] for t in trials[::3]]
    assert len(set(rates)) == 4 and all(1e-4 <= r <= 1e-3 for r in rates)
    assert all(t["n_epochs"] in (5, 10, 20) for t in trials)
    # the same space draws the same trials (a sweep can be made again); random_seed changes them
    assert sweep.trial_values() == trials
    other = sweep_of(hyperparams={"learning_rate": {"loguniform": [1e-4, 1e-3]}},
                     random_seed=1, num_samples=4)
    assert [t["learning_rate"] for t in other.trial_values()] != rates


def test_grid_dimensions_multiply_and_random_seed_is_drawn_per_trial():
    sweep = sweep_of(hyperparams={"n_epochs": {"grid": [5, 10]}, "gamma": {"grid": [0.9, 0.99]}},
                     env_kwargs={"goal_tolerance": {"grid": [0.1, 0.2]}},
                     seed={"randint": [0, 1000]}, num_samples=2)
    trials = sweep.trial_values()
    assert len(trials) == 2 * 2 * 2 * 2
    combos = {(t["n_epochs"], t["gamma"], t["env_kwargs.goal_tolerance"]) for t in trials}
    assert len(combos) == 8
    assert all(isinstance(t["seed"], int) and 0 <= t["seed"] < 1000 for t in trials)
    config = sweep.trial_config(trials[-1])
    assert config["env_kwargs"] == {"goal_tolerance": 0.2}
    assert config["hyperparams"]["n_epochs"] == 10 and config["seed"] == trials[-1]["seed"]


def test_loguniform_draws_are_uniform_in_the_log():
    import numpy as np

    dim = Dimension("loguniform", (1e-4, 1e-2))
    rng = np.random.default_rng(0)
    logs = [math.log10(dim.draw(rng)) for _ in range(4000)]
    assert min(logs) >= -4 and max(logs) <= -2
    # half of the draws below the geometric middle 1e-3
    assert abs(np.mean(np.array(logs) < -3) - 0.5) < 0.03


@pytest.mark.parametrize(("value", "message"), [
    ({"grid": []}, "non-empty list"),
    ({"grid": 3}, "non-empty list"),
    ({"uniform": [1.0]}, "[low, high]"),
    ({"uniform": [2.0, 1.0]}, "low < high"),
    ({"loguniform": [0.0, 1.0]}, "0 < low"),
    ({"randint": [0.5, 3]}, "whole numbers"),
])
def test_bad_dimensions_name_the_key(value, message):
    with pytest.raises(SpaceError, match="space.yaml: hyperparams.learning_rate") as err:
        sweep_of(hyperparams={"learning_rate": value})
    assert message in str(err.value)


def test_a_mapping_that_names_no_dimension_is_a_value():
    value = {"norm_obs": True, "norm_reward": False}
    assert parse_dimension(value, "x") == value
    sweep = sweep_of(hyperparams={"normalize": value})
    assert sweep.trial_config(sweep.trial_values()[0])["hyperparams"]["normalize"] == value


@pytest.mark.parametrize(("data", "message"), [
    ({"algo": "dqn"}, "algo must be one of ppo, sac, td3"),
    ({"learning_rate": 3e-4}, "unknown key(s) learning_rate"),
    ({"hyperparams": {"n_timesteps": 1000}}, "timesteps: (or --timesteps)"),
    ({"hyperparams": {"learnin_rate": {"grid": [1e-4, 3e-4]}}}, "unknown hyperparameter(s)"),
    ({"hyperparams": {"seed": 1}}, "hyperparameter seed cannot be set"),
    ({"hyperparams": {"gamma": {"grid": [0.9, 1.5]}}}, "gamma must be a number in [0, 1]"),
    ({"hyperparams": {"n_envs": 0}}, "n_envs must be a whole number >= 1"),
    ({"seed": {"uniform": [0, 10]}}, "seed must be a whole number"),
    ({"seed": {"grid": [0, 1.5]}}, "seed must be a whole number"),
    ({"timesteps": 0}, "timesteps must be a whole number >= 1"),
    ({"cpus_per_trial": 1.5}, "cpus_per_trial must be a whole number >= 1"),
    ({"eval_freq": 0}, "eval_freq must be a whole number >= 1"),
    ({"early_stopping": {"grace": 10}}, "unknown key(s) grace"),
    ({"early_stopping": {"reduction_factor": 1}}, "reduction_factor must be a number > 1"),
    ({"timesteps": 1000, "early_stopping": {"grace_period": 1000}},
     "grace_period (1000) must be below the steps per trial (1000), or no trial can be "
     "stopped; lower it, or run every trial to the end with --no-early-stopping"),
    ({"early_stopping": "asha"}, "early_stopping must be a mapping"),
    ({"hyperparams": [1, 2]}, "hyperparams must be a mapping"),
    ({"hyperparams_file": "missing.yaml"}, "hyperparams_file"),
    ({"vectorization": "dummy"}, "vectorization must be one of subproc, batched, got 'dummy'"),
])
def test_bad_spaces_are_refused_with_the_key(data, message):
    with pytest.raises(SpaceError, match="space.yaml") as err:
        build_sweep(data, "space.yaml")
    assert message in str(err.value)


def test_space_files_errors_name_the_file(tmp_path):
    with pytest.raises(SpaceError, match="cannot read the search space"):
        load_space(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("hyperparams: [unclosed\n")
    with pytest.raises(SpaceError, match=f"{bad}: not valid YAML"):
        load_space(bad)
    bad.write_text("- a list\n")
    with pytest.raises(SpaceError, match="expected a mapping"):
        load_space(bad)


def test_hyperparams_file_is_read_relative_to_the_space(tmp_path):
    (tmp_path / "mine.yaml").write_text(yaml.safe_dump(
        {"SmartCar-v0": {"n_timesteps": 5000, "n_envs": 2, "policy": "MlpPolicy",
                         "n_steps": 64}}))
    space = tmp_path / "space.yaml"
    space.write_text(yaml.safe_dump({"hyperparams_file": "mine.yaml",
                                     "hyperparams": {"batch_size": {"grid": [32, 64]}}}))
    data, path = load_space(space)
    sweep = build_sweep(data, path, path.parent)
    assert sweep.timesteps == 5000  # the file's n_timesteps
    config = sweep.trial_config(sweep.trial_values()[1])
    # only the file's values and the space's: nothing of the shipped ppo.yaml
    assert config["hyperparams"] == {"n_envs": 2, "policy": "MlpPolicy", "n_steps": 64,
                                     "batch_size": 64}


def test_command_line_overrides(tmp_path):
    data, _ = load_space()
    data = apply_overrides(data, [("learning_rate", 1e-3), ("ent_coef", {"grid": [0.0, 0.01]})],
                           [7, 8, 9], timesteps=40960, num_samples=None)
    sweep = build_sweep(data, "cli")
    assert sweep.timesteps == 40960 and sweep.num_samples == 1
    assert sweep.seed == Dimension("grid", (7, 8, 9))
    assert sweep.hyperparams["learning_rate"] == 1e-3
    assert set(sweep.dimensions()) == {"ent_coef", "n_epochs", "seed"}
    assert len(sweep.trial_values()) == 2 * 2 * 3


def test_n_envs_defaults_to_the_cpus_of_a_trial(tmp_path):
    (tmp_path / "bare.yaml").write_text(yaml.safe_dump(
        {"SmartCar-v0": {"n_timesteps": 5000}}))
    sweep = build_sweep({"hyperparams_file": str(tmp_path / "bare.yaml"), "cpus_per_trial": 3},
                        "space.yaml")
    # smartcar-train would take the node's CPU count; the sweep fixes it to the trial's CPUs
    assert sweep.hyperparams["n_envs"] == 3 and sweep.hyperparams["policy"] == "MlpPolicy"
    assert sweep.early_stopping is None  # only a space that asks for ASHA gets it


def test_asha_defaults():
    sweep = sweep_of(timesteps=100_000, eval_freq=5000, early_stopping={})
    assert sweep.early_stopping == {"grace_period": 10_000, "reduction_factor": 2}


def test_sweep_yaml_round_trip(tmp_path):
    sweep = sweep_of(hyperparams={"learning_rate": {"loguniform": [1e-4, 1e-3]}},
                     env_kwargs={"goal_tolerance": {"grid": [0.1, 0.2]}},
                     seed={"grid": [0, 1]}, timesteps=4096, early_stopping=None)
    again = build_sweep(yaml.safe_load(yaml.safe_dump(sweep.to_yaml())), "sweep.yaml")
    assert again.trial_values() == sweep.trial_values()
    assert again.early_stopping is None and again.timesteps == 4096
    assert env_kwargs_samples(again) == [{"goal_tolerance": 0.1}, {"goal_tolerance": 0.2}]


def test_a_batched_sweep_yaml_is_the_same_sweep_again():
    """What --resume reads back: the batched entry's values, the vectorization, the CPUs."""
    sweep = sweep_of(vectorization="batched", env_kwargs={"engine": "planar"})
    again = build_sweep(yaml.safe_load(yaml.safe_dump(sweep.to_yaml())), "sweep.yaml")
    assert (again.vectorization, again.cpus_per_trial, again.timesteps) == ("batched", 2, 262144)
    assert again.hyperparams == sweep.hyperparams and again.hyperparams["eval_async"] is True


def test_numbers_without_a_dot_are_numbers_in_dimensions():
    # PyYAML reads 1e-4 as a string; smartcar-train's --hyperparams reads it as a number
    from smartcar_gym.agents.hyperparams import parse_value

    value = parse_value("{loguniform: [1e-4, 1e-3]}")
    assert value == {"loguniform": ["1e-4", "1e-3"]}
    sweep = sweep_of(hyperparams={"learning_rate": value,
                                  "policy_kwargs": {"choice": ["dict(net_arch=[64])"]}},
                     env_kwargs={"wheel_contact": {"grid": ["sphere", "urdf"]}})
    assert sweep.hyperparams["learning_rate"] == Dimension("loguniform", (1e-4, 1e-3))
    assert sweep.env_kwargs["wheel_contact"] == Dimension("grid", ("sphere", "urdf"))
    assert sweep.hyperparams["policy_kwargs"].values == ("dict(net_arch=[64])",)


@pytest.mark.parametrize(("timesteps", "eval_freq", "eval_start", "grace"), [
    (30720, 10240, 0, 10240),     # half is 15,360 steps: the evaluation at 10,240
    (20480, 10240, 0, 10240),     # half is the first evaluation
    (20479, 10240, 0, None),      # half is 10,239 steps: no evaluation in it
    (4096, 10240, 0, None),       # the only evaluation is the final one
    (4096, 512, 0, 2048),         # evaluations every 512 steps: the 4th is half-way
    (4096, 512, 2100, None),      # the first evaluation (2,560) is past half-way
    (1_000_000, 10240, 20000, 491520),
])
def test_grace_period_fits_the_last_evaluation_in_the_first_half(timesteps, eval_freq,
                                                                 eval_start, grace):
    assert fit_grace_period(timesteps, eval_freq, eval_start) == grace


def test_a_grace_period_too_long_for_the_trial_is_scaled_or_dropped_with_a_note():
    data, path = load_space()  # grace_period 30720, eval_freq 10240
    fits = build_sweep({**data, "timesteps": 30721}, path, fit_early_stopping=True)
    assert fits.early_stopping == {"grace_period": 30720, "reduction_factor": 2}
    assert fits.notes == []
    scaled = build_sweep({**data, "timesteps": 30720}, path, fit_early_stopping=True)
    assert scaled.early_stopping == {"grace_period": 10240, "reduction_factor": 2}
    assert scaled.notes == ["early_stopping.grace_period 30720 is not below the 30720 steps per "
                            "trial: scaled to 10240 (the last evaluation in a trial's first "
                            "half); --no-early-stopping runs every trial to the end"]
    quick = build_sweep({**data, "timesteps": 4096}, path, fit_early_stopping=True)
    assert quick.early_stopping is None
    assert quick.notes == ["no early stopping: early_stopping.grace_period (30720) is not below "
                           "the 4096 steps per trial, and a trial has no evaluation (every 10240 "
                           "steps) in its first half to scale it to; every trial runs to the end "
                           "(as with --no-early-stopping)"]
    # what sweep.yaml keeps: the scaled values, which --resume reads without a note
    again = build_sweep(yaml.safe_load(yaml.safe_dump(scaled.to_yaml())), "sweep.yaml")
    assert again.early_stopping == scaled.early_stopping and again.notes == []
    # grace_period left to its default (2 evaluations) is fitted without fit_early_stopping
    short = sweep_of(timesteps=1000, eval_freq=500, early_stopping={})
    assert short.early_stopping == {"grace_period": 500, "reduction_factor": 2}
    assert short.notes[0].startswith("early_stopping.grace_period 1000 is not below the 1000 "
                                     "steps per trial: scaled to 500")
    with pytest.raises(SpaceError, match="--no-early-stopping"):  # set beside its timesteps
        build_sweep({**data, "timesteps": 4096}, path)
