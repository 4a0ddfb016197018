"""One trial of a ``smartcar-tune`` sweep: a ``smartcar-train`` run in ``<out>/trial_<n>/``.

The trial writes its hyperparameters to ``<out>/trial_<n>/hyperparams.yaml`` (zoo format)
and runs ``agents.training.train`` on the config ``smartcar-train`` would make from the
equivalent command line (recorded as ``command`` in ``config.yaml``), so the folder is an
ordinary run folder: ``smartcar-eval``, ``smartcar-train --resume`` and the plots work on it.

Each evaluation is reported to Tune (``success_rate``, ``mean_reward``, ``timesteps``, ...)
after its checkpoint and best model are saved: a scheduler (ASHA) that stops the trial at a
report stops it with everything up to that evaluation on disk. A trial that starts again
(Tune's restore after a crash, or a retry) continues from the latest checkpoint of its run
folder, as ``smartcar-train --resume`` does.

A batched trial (``vectorization: batched``) steps its cars on as many threads as the CPUs Ray
reserved for it (``cpus_per_trial``), not one per CPU of the node.
"""

from __future__ import annotations

import json
import shlex
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

import yaml
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import KVWriter

from smartcar_gym.agents.callbacks import atomic_write_text
from smartcar_gym.agents.cli_train import build_parser
from smartcar_gym.agents.hyperparams import HyperparamsError
from smartcar_gym.agents.runs import new_run, resume_config, saved_models
from smartcar_gym.agents.training import RunSetupError, train
from smartcar_gym.scale.space import Sweep

EVAL_KEYS = ("success_rate", "mean_reward", "std_reward", "mean_final_distance",
             "mean_ep_length")
TRIAL_KEY = "trial"  # Tune's config of a trial: {"trial": <its searched values>}
TIME_FILE = "tune_trial.json"  # the trial's wall time over its segments, updated at each report


class TrialSetupError(RuntimeError):
    """A trial's run cannot be made or continued (the message names the folder and why)."""


def trial_folder(trial_id: str) -> str:
    """``trial_<n>`` from Tune's trial id ``<experiment hash>_<n>`` (stable across restores)."""
    return "trial_" + trial_id.rsplit("_", 1)[-1]


def plain(value: Any) -> Any:
    """``value`` with numpy scalars (Tune's samples) turned into Python numbers, for YAML."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value.item() if hasattr(value, "item") and hasattr(value, "dtype") else value


def yaml_value(value: Any) -> str:
    """A value as a one-line YAML flow scalar, as ``key=value`` arguments take it."""
    return yaml.safe_dump(plain(value), default_flow_style=True, width=10**6).strip() \
        .removesuffix("...").strip()


def train_argv(config: dict[str, Any], run_dir: Path, hyperparams_file: Path) -> list[str]:
    """The ``smartcar-train`` arguments of a trial (its hyperparameters are in the file)."""
    argv = ["--algo", config["algo"], "--env", config["env"], "--seed", str(config["seed"]),
            "--hyperparams-file", str(hyperparams_file), "--run-dir", str(run_dir),
            "--eval-freq", str(config["eval_freq"]), "--eval-episodes",
            str(config["eval_episodes"]), "--eval-start", str(config["eval_start"]),
            # a checkpoint at every evaluation: a trial stopped at a report loses nothing
            "--checkpoint-freq", str(config["eval_freq"]), "--no-progress"]
    if config.get("vectorization", "subproc") != "subproc":
        argv += ["--vectorization", config["vectorization"]]
    if config.get("env_kwargs"):
        argv += ["--env-kwargs", *(f"{k}={yaml_value(v)}" for k, v in
                                   config["env_kwargs"].items())]
    return argv


def trial_hyperparams(config: dict[str, Any]) -> dict[str, Any]:
    """The trial's complete hyperparameters (zoo entry), ``n_timesteps`` included."""
    return {**plain(config["hyperparams"]), "n_timesteps": int(config["timesteps"])}


class EvalCapture(KVWriter):
    """An SB3 logger output that keeps the values of each evaluation dump until taken."""

    def __init__(self) -> None:
        self.found: list[dict[str, float]] = []

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, Any],
              step: int = 0) -> None:
        if "eval/success_rate" in key_values:
            values = {key: float(key_values[f"eval/{key}"]) for key in EVAL_KEYS
                      if f"eval/{key}" in key_values}
            self.found.append({**values, "timesteps": int(step)})

    def take(self) -> list[dict[str, float]]:
        """The evaluations dumped since the last call, in order."""
        found, self.found = self.found, []
        return found

    def close(self) -> None:
        pass


class ReportEvaluations(BaseCallback):
    """Pass each evaluation to ``report`` once its checkpoint and best model are saved (this
    callback runs after them). Evaluations at or past ``target`` steps are left to the caller,
    which reports the run's final evaluation after ``train`` returns, when every file of the
    run is written. ``flush`` reports those that came after the last step: a batched run's
    ``eval_async`` evaluations still running when training ended."""

    def __init__(self, report: Callable[[dict[str, Any]], None], target: int) -> None:
        super().__init__()
        self.report = report
        self.target = int(target)
        self.capture = EvalCapture()

    def _on_training_start(self) -> None:
        self.model.logger.output_formats.append(self.capture)

    def _on_step(self) -> bool:
        self.flush()
        return True

    def flush(self) -> None:
        """Report the evaluations captured and not reported yet (before ``target``)."""
        for evaluation in self.capture.take():
            if evaluation["timesteps"] < self.target:
                self.report(evaluation)


def run_trial(config: dict[str, Any], out: str, sweep: Sweep) -> None:
    """Tune's function trainable: train (or continue) the run of ``sweep`` with the searched
    values ``config["trial"]`` (see ``Sweep.trial_values``) in ``<out>/trial_<n>`` and report
    its evaluations."""
    import ray
    import torch
    from ray import tune

    torch.set_num_threads(1)
    config = sweep.trial_config(plain(config[TRIAL_KEY]))
    run_dir = Path(out) / trial_folder(tune.get_context().get_trial_id())
    node_id = ray.get_runtime_context().get_node_id()
    started, earlier = time.monotonic(), _earlier_wall_time(run_dir)
    run_config, checkpoint, command = prepare_run(config, run_dir)

    def report(metrics: dict[str, Any]) -> None:
        metrics = {**metrics, "wall_time_s": earlier + time.monotonic() - started,
                   "node_id": node_id}
        atomic_write_text(run_dir / TIME_FILE, json.dumps(metrics, indent=2) + "\n")
        tune.report(metrics)

    reporter = ReportEvaluations(report, int(run_config["n_timesteps"]))
    try:
        result = train(run_config, run_dir, checkpoint=checkpoint, command=command,
                       progress=False, extra_callbacks=[reporter], threads=trial_threads(sweep))
    except (RunSetupError, HyperparamsError) as err:
        raise TrialSetupError(f"{run_dir}: {err}") from None
    reporter.flush()  # eval_async: the evaluations that came in after the last step
    final = result.final_eval or result.best_eval
    if final is None:
        raise TrialSetupError(f"{run_dir}: the run ended without an evaluation")
    report({**{key: final[key] for key in EVAL_KEYS}, "timesteps": result.num_timesteps})


def trial_threads(sweep: Sweep) -> int | None:
    """The worker threads of a batched trial's cars: the CPUs Ray reserved for it (a subproc
    trial's envs are processes: None)."""
    return sweep.cpus_per_trial if sweep.vectorization == "batched" else None


def prepare_run(config: dict[str, Any], run_dir: Path,
                ) -> tuple[dict[str, Any], Path | None, str]:
    """The run config, checkpoint to continue from (None: a new run) and command of a trial.

    A run folder with a checkpoint is continued; its config must be this trial's.
    """
    parser = build_parser()

    def fail(message: str) -> NoReturn:
        raise TrialSetupError(f"{run_dir}: {message}")

    parser.error = fail  # type: ignore[method-assign]  # run_folder reports through it
    if (run_dir / "config.yaml").is_file() and saved_models(run_dir, "ckpt_*_steps.zip"):
        argv = ["--resume", str(run_dir), "--no-progress"]
        run_config, _, checkpoint = resume_config(parser, parser.parse_args(argv))
        check_same_trial(run_config, config, run_dir)
        return run_config, checkpoint, shlex.join(["smartcar-train", *argv])
    hyperparams_file = run_dir / "hyperparams.yaml"
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(hyperparams_file, yaml.safe_dump(
        {config["env"]: trial_hyperparams(config)}, sort_keys=False))
    argv = train_argv(config, run_dir, hyperparams_file)
    run_config, _ = new_run(parser, parser.parse_args(argv), shlex.join(["smartcar-train",
                                                                         *argv]))
    return run_config, None, run_config["command"]


def check_same_trial(run_config: dict[str, Any], config: dict[str, Any], run_dir: Path) -> None:
    """Refuse to continue a run folder that holds a run of other settings than the trial's."""
    ours = {"algo": config["algo"], "env": config["env"],
            "vectorization": config.get("vectorization", "subproc"), "seed": plain(config["seed"]),
            "env_kwargs": plain(config.get("env_kwargs") or {}),
            "hyperparams": trial_hyperparams(config)}
    ours = yaml.safe_load(yaml.safe_dump(ours))  # as config.yaml holds them (lists, not tuples)
    theirs = {key: run_config.get(key) for key in ours}
    theirs["hyperparams"] = {**(run_config.get("hyperparams") or {}),
                             "n_timesteps": int(config["timesteps"])}
    differ = sorted(key for key in ours if ours[key] != theirs[key])
    if differ:
        raise TrialSetupError(
            f"{run_dir} holds a run with other {', '.join(differ)} than this trial "
            f"({ {k: theirs[k] for k in differ} } vs { {k: ours[k] for k in differ} }); move it "
            "away or sweep into another --out"
        )


def _earlier_wall_time(run_dir: Path) -> float:
    try:
        return float(json.loads((run_dir / TIME_FILE).read_text())["wall_time_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return 0.0

