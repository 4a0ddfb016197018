"""smartcar-tune results: trial status, ranking over seeds, the files written."""

from __future__ import annotations

import csv
import json
import shlex

import pytest

from smartcar_gym.agents.cli_train import build_parser
from smartcar_gym.agents.hyperparams import load_hyperparams
from smartcar_gym.agents.runs import new_config
from smartcar_gym.scale.results import (
    COMPLETED,
    ERROR,
    STOPPED,
    UNFINISHED,
    TrialRow,
    best_group,
    trial_status,
    write_results,
)

HP = {"n_envs": 1, "policy": "MlpPolicy", "n_steps": 64, "batch_size": 32, "n_epochs": 1}


def row(trial, lr, seed, success, ret, steps=4096, status=COMPLETED):
    return TrialRow(trial=trial, status=status, values={"learning_rate": lr, "seed": seed},
                    success_rate=success, mean_reward=ret, timesteps=steps, wall_time_s=10.0,
                    hyperparams={**HP, "learning_rate": lr, "n_timesteps": 4096}, seed=seed,
                    run_dir=f"/out/{trial}")


@pytest.mark.parametrize(("tune_status", "steps", "error", "expected"), [
    ("TERMINATED", 4096, False, COMPLETED),
    ("TERMINATED", 5000, False, COMPLETED),  # PPO ends on a whole rollout
    ("TERMINATED", 2048, False, STOPPED),    # ASHA stopped it at 2048 steps
    ("ERROR", 2048, False, ERROR),
    ("TERMINATED", None, True, ERROR),
    ("RUNNING", 2048, False, UNFINISHED),    # the sweep was interrupted
    ("PENDING", None, False, UNFINISHED),
])
def test_trial_status(tune_status, steps, error, expected):
    assert trial_status(tune_status, steps, 4096, error) == expected


def test_best_configuration_is_ranked_by_its_mean_over_seeds():
    rows = [row("trial_00000", 1e-4, 0, 1.0, 9.0), row("trial_00001", 1e-4, 1, 0.2, 1.0),
            row("trial_00002", 3e-4, 0, 0.8, 5.0), row("trial_00003", 3e-4, 1, 0.8, 5.0)]
    group, success, mean_return = best_group(rows)
    # 1e-4 has the single best trial, 3e-4 the better mean (0.8 vs 0.6)
    assert [r.trial for r in group] == ["trial_00002", "trial_00003"]
    assert success == pytest.approx(0.8) and mean_return == pytest.approx(5.0)


def test_equal_success_is_decided_by_return_and_rows_without_results_do_not_count():
    rows = [row("trial_00000", 1e-4, 0, 0.5, 2.0), row("trial_00001", 3e-4, 0, 0.5, 3.0),
            row("trial_00002", 1e-3, 0, None, None, None, ERROR),
            row("trial_00003", 1e-3, 1, float("nan"), 0.0)]
    group, success, _ = best_group(rows)
    assert [r.trial for r in group] == ["trial_00001"] and success == 0.5
    assert best_group(rows[2:]) is None


def test_written_results_and_best_hyperparameters(tmp_path):
    rows = [row("trial_00000", 1e-4, 0, 0.25, -1.0, 2048, STOPPED),
            row("trial_00001", 3e-4, 0, 0.9, 8.0), row("trial_00002", 3e-4, 1, 0.7, 6.0),
            row("trial_00003", 1e-3, 0, None, None, None, ERROR)]
    rows[3].error = "RuntimeError: boom"
    written = write_results(rows, ["learning_rate", "seed"], tmp_path, "ppo", "SmartCar-v0")
    assert [p.name for p in written] == ["results.csv", "results.json", "best_hyperparams.yaml"]
    with open(tmp_path / "results.csv") as f:
        table = list(csv.DictReader(f))
    assert list(table[0])[:8] == ["trial", "status", "learning_rate", "seed", "success_rate",
                                  "mean_reward", "timesteps", "wall_time_s"]
    assert [r["status"] for r in table] == [STOPPED, COMPLETED, COMPLETED, ERROR]
    assert table[0]["timesteps"] == "2048" and table[3]["error"] == "RuntimeError: boom"
    summary = json.loads((tmp_path / "results.json").read_text())
    assert summary["best"]["trials"] == ["trial_00001", "trial_00002"]
    assert summary["best"]["mean_success_rate"] == pytest.approx(0.8)
    assert summary["best"]["values"] == {"learning_rate": 3e-4}
    assert summary["trials"][1]["hyperparams"]["learning_rate"] == 3e-4

    # the best file is a hyperparameter file smartcar-train reads, and its header says how
    best = tmp_path / "best_hyperparams.yaml"
    assert load_hyperparams("ppo", "SmartCar-v0", best) == {
        **HP, "learning_rate": 3e-4, "n_timesteps": 4096}
    command = next(line for line in best.read_text().splitlines() if "Train it with:" in line)
    argv = shlex.split(command.split("Train it with: ", 1)[1])
    assert argv[0] == "smartcar-train"
    config = new_config(build_parser().parse_args(argv[1:]), command)
    assert config["hyperparams"]["learning_rate"] == 3e-4 and config["n_timesteps"] == 4096
    assert config["n_envs"] == 1 and config["seed"] == 0


def test_no_best_file_when_no_trial_was_evaluated(tmp_path):
    rows = [row("trial_00000", 1e-4, 0, None, None, None, ERROR)]
    written = write_results(rows, ["learning_rate", "seed"], tmp_path, "ppo", "SmartCar-v0")
    assert [p.name for p in written] == ["results.csv", "results.json"]
    assert json.loads((tmp_path / "results.json").read_text())["best"] is None


def test_best_file_command_carries_env_kwargs(tmp_path):
    best = row("trial_00000", 1e-4, 3, 1.0, 1.0)
    best.env_kwargs = {"goal_range": [0.5, 0.6], "wheel_contact": "urdf"}
    write_results([best], ["learning_rate", "seed"], tmp_path / "my sweep", "ppo", "SmartCar-v0")
    text = (tmp_path / "my sweep" / "best_hyperparams.yaml").read_text()
    command = next(line for line in text.splitlines() if "Train it with:" in line)
    args = build_parser().parse_args(shlex.split(command.split("Train it with: ", 1)[1])[1:])
    assert dict(args.env_kwargs) == {"goal_range": [0.5, 0.6], "wheel_contact": "urdf"}
    assert args.seed == 3 and args.vectorization is None  # a subproc sweep: the default
    assert args.hyperparams_file == tmp_path / "my sweep" / "best_hyperparams.yaml"


def test_a_batched_sweep_s_best_file_trains_batched(tmp_path):
    """The command a batched sweep's best file gives runs its cars in one process, as its
    trials did (not 32 subprocess envs)."""
    best = row("trial_00000", 1e-4, 1, 1.0, 1.0)
    best.env_kwargs = {"engine": "planar"}
    write_results([best], ["learning_rate", "seed"], tmp_path, "ppo", "SmartCar-v0", "batched")
    text = (tmp_path / "best_hyperparams.yaml").read_text()
    command = next(line for line in text.splitlines() if "Train it with:" in line)
    args = build_parser().parse_args(shlex.split(command.split("Train it with: ", 1)[1])[1:])
    assert args.vectorization == "batched" and dict(args.env_kwargs) == {"engine": "planar"}
