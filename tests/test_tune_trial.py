"""A smartcar-tune trial as a smartcar-train run: its config, its folder, its reports.

These run without Ray: the trial's run is made and trained by the same functions Tune calls.
"""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest
import yaml

from smartcar_gym.agents.cli_train import build_parser
from smartcar_gym.agents.hyperparams import parse_value
from smartcar_gym.agents.training import train
from smartcar_gym.scale.space import build_sweep
from smartcar_gym.scale.trial import (
    ReportEvaluations,
    TrialSetupError,
    plain,
    prepare_run,
    trial_folder,
    trial_threads,
    yaml_value,
)

TINY = {"n_envs": 1, "n_steps": 128, "batch_size": 64, "n_epochs": 1}
# the batched planar preset, shrunk: 4 cars x 32 steps, evaluated in a second process
TINY_BATCHED = {"n_envs": 4, "n_steps": 32, "batch_size": 64, "n_epochs": 1,
                "policy_kwargs": "dict(net_arch=[16, 16])"}


def trial_config(**space):
    sweep = build_sweep({"timesteps": 384, "eval_freq": 128, "eval_episodes": 1,
                         "hyperparams": {**TINY, "learning_rate": {"grid": [1e-4, 3e-4]}},
                         "seed": {"grid": [5]}, **space}, "space.yaml")
    return sweep.trial_config(sweep.trial_values()[1])


def test_trial_folder_names_come_from_the_trial_index():
    assert trial_folder("a1b2c_00007") == "trial_00007"
    assert trial_folder("a1b2c_00123") == "trial_00123"


@pytest.mark.parametrize("value", [3e-4, 1e-10, 0.1, 2048, True, "urdf", [0.5, 1.5],
                                   "dict(net_arch=[64, 64])", {"norm_obs": True}])
def test_values_survive_the_command_line(value):
    assert parse_value(yaml_value(value)) == value


def test_numpy_samples_become_python_numbers():
    value = plain({"a": np.float64(0.5), "b": [np.int64(3)], "c": "x"})
    assert value == {"a": 0.5, "b": [3], "c": "x"}
    assert type(value["a"]) is float and type(value["b"][0]) is int


def test_a_new_trial_is_the_run_of_its_smartcar_train_command(tmp_path):
    config = trial_config(env_kwargs={"goal_range": [0.5, 1.0]})
    run_dir = tmp_path / "trial_00001"
    run_config, checkpoint, command = prepare_run(config, run_dir)
    assert checkpoint is None
    saved = yaml.safe_load((run_dir / "hyperparams.yaml").read_text())
    assert saved == {"SmartCar-v0": {**config["hyperparams"], "n_timesteps": 384}}
    assert saved["SmartCar-v0"]["learning_rate"] == 3e-4
    # the recorded command makes the same config when run by hand
    argv = shlex.split(command)
    assert argv[0] == "smartcar-train"
    args = build_parser().parse_args(argv[1:])
    assert args.run_dir == run_dir and args.seed == 5
    assert run_config["hyperparams"] == saved["SmartCar-v0"]
    assert run_config["env_kwargs"] == {"goal_range": [0.5, 1.0]}
    assert (run_config["n_envs"], run_config["n_timesteps"]) == (1, 384)
    assert (run_config["eval_freq"], run_config["eval_episodes"], run_config["eval_start"]) == (
        128, 1, 0)
    # a checkpoint at every evaluation: a trial stopped at a report has that step on disk
    assert run_config["checkpoint_freq"] == 128


def test_evaluations_are_reported_after_their_files_and_the_last_one_after_train(tmp_path):
    config = trial_config()
    run_dir = tmp_path / "trial_00001"
    run_config, _, command = prepare_run(config, run_dir)
    seen = []

    def report(metrics):
        steps = metrics["timesteps"]
        on_disk = np.load(run_dir / "eval" / "evaluations.npz")["timesteps"].tolist()
        seen.append((steps, (run_dir / "checkpoints" / f"ckpt_{steps}_steps.zip").is_file(),
                     steps in on_disk, (run_dir / "best_model.json").is_file()))
        assert 0.0 <= metrics["success_rate"] <= 1.0 and "mean_reward" in metrics

    result = train(run_config, run_dir, command=command, progress=False,
                   extra_callbacks=[ReportEvaluations(report, 384)])
    # evaluations at 128 and 256 during learn(); the one at 384 (the target) is not reported
    # from inside learn(), where a scheduler's stop would cut off the run's last files
    assert seen == [(128, True, True, True), (256, True, True, True)]
    assert result.num_timesteps == 384 and result.final_eval["timesteps"] == 384
    assert (run_dir / "summary.json").is_file() and (run_dir / "model.zip").is_file()


def test_a_trial_continues_its_own_run_and_refuses_another(tmp_path):
    config = trial_config()
    run_dir = tmp_path / "trial_00001"
    run_config, _, command = prepare_run(config, run_dir)
    run_config["n_timesteps"] = 256  # a run that stopped before its 384 steps
    train(run_config, run_dir, command=command, progress=False)
    assert (run_dir / "checkpoints" / "ckpt_256_steps.zip").is_file()

    again, checkpoint, command = prepare_run(config, run_dir)
    assert checkpoint == run_dir / "checkpoints" / "ckpt_256_steps.zip"
    assert command == f"smartcar-train --resume {run_dir} --no-progress"
    assert again["seed"] == 5 and again["hyperparams"]["learning_rate"] == 3e-4

    other = trial_config(seed={"grid": [6]})
    with pytest.raises(TrialSetupError, match=r"trial_00001 holds a run with other seed"):
        prepare_run(other, run_dir)
    config["hyperparams"]["n_epochs"] = 2
    with pytest.raises(TrialSetupError, match="other hyperparams"):
        prepare_run(config, run_dir)


def test_a_folder_holding_a_foreign_model_is_refused_with_its_name(tmp_path):
    run_dir = tmp_path / "trial_00000"
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text(json.dumps({"algo": "ppo"}))
    (run_dir / "best_model.zip").write_bytes(b"not ours")
    with pytest.raises(TrialSetupError, match=r"trial_00000: .*best_model.zip"):
        prepare_run(trial_config(), run_dir)


def batched_trial(cpus_per_trial=1):
    sweep = build_sweep({"vectorization": "batched", "timesteps": 384, "eval_freq": 128,
                         "eval_episodes": 1, "cpus_per_trial": cpus_per_trial,
                         "hyperparams": TINY_BATCHED, "seed": 5,
                         "env_kwargs": {"engine": "planar", "goal_range": [0.3, 0.4]}},
                        "space.yaml")
    return sweep, sweep.trial_config(sweep.trial_values()[0])


def test_a_batched_trial_is_the_run_of_smartcar_train_s_batched_command(tmp_path):
    sweep, config = batched_trial()
    run_dir = tmp_path / "trial_00000"
    run_config, _, command = prepare_run(config, run_dir)
    argv = shlex.split(command)
    assert argv[argv.index("--vectorization") + 1] == "batched"
    assert build_parser().parse_args(argv[1:]).vectorization == "batched"
    # the planar preset's settings: its own cars, evaluated on planar in a second process
    assert (run_config["vectorization"], run_config["n_envs"]) == ("batched", 4)
    assert (run_config["eval_engine"], run_config["eval_async"]) == (None, True)
    assert trial_threads(sweep) == 1 and trial_threads(batched_trial(3)[0]) == 3
    assert trial_threads(build_sweep({"cpus_per_trial": 3}, "space.yaml")) is None
    # a subproc run in the folder is not this trial's
    subproc = {**config, "vectorization": "subproc"}
    run_config["n_timesteps"] = 128
    train(run_config, run_dir, command=command, progress=False)
    with pytest.raises(TrialSetupError, match="other vectorization"):
        prepare_run(subproc, run_dir)


class Threads(ReportEvaluations):
    """ReportEvaluations that also notes the thread count of the cars it trains on."""

    def _on_training_start(self):
        super()._on_training_start()
        venv = self.model.get_env()
        while hasattr(venv, "venv"):
            venv = venv.venv
        self.threads = venv.unwrapped.threads


def test_a_batched_trial_reports_every_evaluation_on_its_threads(tmp_path):
    """eval_async results come in while training goes on, or after its last step: each is
    reported, in order, after its checkpoint, the final one after train (as run_trial does)."""
    sweep, config = batched_trial(cpus_per_trial=2)
    run_dir = tmp_path / "trial_00000"
    run_config, _, command = prepare_run(config, run_dir)
    seen = []

    def report(metrics):
        steps = metrics["timesteps"]
        seen.append((steps, (run_dir / "checkpoints" / f"ckpt_{steps}_steps.zip").is_file()))

    reporter = Threads(report, 384)
    result = train(run_config, run_dir, command=command, progress=False,
                   extra_callbacks=[reporter], threads=trial_threads(sweep))
    reporter.flush()
    assert reporter.threads == 2
    assert seen == [(128, True), (256, True)]
    assert result.final_eval["timesteps"] == 384
    assert np.load(run_dir / "eval" / "evaluations.npz")["timesteps"].tolist() == [128, 256, 384]


def test_evaluations_logged_after_the_last_step_are_reported_once_by_flush():
    seen = []
    reporter = ReportEvaluations(seen.append, 384)
    for steps in (128, 256, 384):  # eval_async's results, drained when training ended
        reporter.capture.write({"eval/success_rate": steps / 384, "eval/mean_reward": 1.0}, {},
                               steps)
    reporter.flush()
    reporter.flush()
    assert seen == [{"success_rate": 1 / 3, "mean_reward": 1.0, "timesteps": 128},
                    {"success_rate": 2 / 3, "mean_reward": 1.0, "timesteps": 256}]
