"""A ``smartcar-train`` run's folder: a new run's config and folder, the run to resume, the
names of its checkpoints.

A run folder holds ``config.yaml`` (what ran), ``model.zip`` (+ ``vecnormalize.pkl``),
``checkpoints/``, ``best_model.zip``, ``eval/evaluations.npz``, ``monitor/*.monitor.csv``,
``tb/`` (TensorBoard), ``summary.json`` and ``learning_curve.png``. A checkpoint
``checkpoints/ckpt_<steps>_steps.zip`` has its ``.json`` and, with ``--save-replay-buffer``,
its ``_replay_buffer.pkl``. Files are written by ``atomic_files``.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import shutil
import sys
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents import zoo_keys
from smartcar_gym.agents.atomic_files import output_path_error
from smartcar_gym.agents.env_factory import EnvSetupError, check_env_id
from smartcar_gym.agents.hyperparams import (
    ALGOS,
    HyperparamsError,
    build_algo_kwargs,
    discount,
    hyperparams_variant,
    load_hyperparams,
    normalize_kwargs,
    policy_class,
    run_int,
)
from smartcar_gym.agents.models import saved_algo, vecnormalize_path_for
from smartcar_gym.sim.engines import check_engine

DEFAULT_ENV_ID = "SmartCar-v0"
# Settings that come from the run's config.yaml when resuming and cannot be changed then.
FIXED_ON_RESUME = ("algo", "env_id", "n_envs", "seed", "hyperparams", "env_kwargs",
                   "hyperparams_file", "run_dir", "vectorization")
# Keys of config.yaml that --resume needs.
REQUIRED_KEYS = ("algo", "env", "seed", "n_envs", "n_timesteps", "hyperparams", "eval_freq",
                 "eval_episodes", "checkpoint_freq")
# What smartcar-train writes in a run folder (removed when a run that never saved a checkpoint
# or a model is started again).
RUN_FOLDERS = ("monitor", "tb", "eval", "checkpoints")
CHECKPOINT_RE = re.compile(r"^ckpt_(\d+)_steps\.zip$")
RUN_FILES = ("config.yaml", "summary.json", "learning_curve.png", "vecnormalize.pkl", "error.log",
             "best_model.json", "best_model_vecnormalize.pkl", *RUN_FOLDERS)


def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import smartcar_gym

    versions = {"smartcar_gym": smartcar_gym.__version__, "stable_baselines3":
                stable_baselines3.__version__, "torch": torch.__version__,
                "gymnasium": gymnasium.__version__, "python": platform.python_version()}
    return {name: str(version) for name, version in versions.items()}


def utc_timestamp() -> str:
    """The current UTC time, ISO 8601 to the second (as written in config.yaml)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _eval_setting(given: int | None, hyperparams: dict[str, Any], key: str, default: int) -> int:
    """``--eval-freq``/``--eval-episodes`` if given, else the hyperparameters' ``key`` (a whole
    number: >= 0 for ``eval_freq``, whose 0 turns evaluations off; >= 1 for
    ``eval_episodes``), else ``default``."""
    if given is not None:
        return given
    value = run_int(hyperparams, key, least=0 if key == "eval_freq" else 1)
    return default if value is None else value


def new_config(args: argparse.Namespace, command: str) -> dict[str, Any]:
    """The config of a new run from parsed arguments; raises ``HyperparamsError``."""
    algo = args.algo or "ppo"
    env_id = args.env_id or DEFAULT_ENV_ID
    vectorization = getattr(args, "vectorization", None) or "subproc"
    engine = dict(args.env_kwargs or []).get("engine")
    variant = hyperparams_variant(vectorization, engine)
    check_env_id(env_id)  # an unknown id is the id's fault, not the hyperparameter file's
    hyperparams = load_hyperparams(algo, env_id, args.hyperparams_file, variant=variant)
    hyperparams.update(dict(args.hyperparams or []))
    file_n_envs, file_timesteps = run_int(hyperparams, "n_envs"), run_int(hyperparams,
                                                                       "n_timesteps")
    n_envs = args.n_envs or file_n_envs or os.cpu_count() or 1
    timesteps = args.timesteps or file_timesteps
    if not timesteps:
        raise HyperparamsError(f"no n_timesteps for {env_id} in the {algo} hyperparameters; "
                               "pass --timesteps")
    hyperparams["n_envs"], hyperparams["n_timesteps"] = int(n_envs), int(timesteps)
    hyperparams.setdefault("policy", "MlpPolicy")
    normalize_kwargs(hyperparams.get("normalize"))  # validate early
    discount(hyperparams)
    build_algo_kwargs(algo, hyperparams, n_actions=1)  # validate early
    policy_class(hyperparams)
    zoo_keys.check(hyperparams)
    env_kwargs = {**zoo_keys.env_kwargs(hyperparams.get("env_kwargs")),
                  **dict(args.env_kwargs or [])}  # the command line wins, key by key
    seed = 0 if args.seed is None else args.seed
    eval_engine = getattr(args, "eval_engine", None) or hyperparams.get("eval_engine")
    if eval_engine is not None:
        try:
            check_engine(eval_engine, "eval_engine")
        except ValueError as err:
            raise HyperparamsError(str(err)) from None
    if not isinstance(hyperparams.get("eval_async", False), bool):
        raise HyperparamsError(f"eval_async must be true or false, got "
                               f"{hyperparams['eval_async']!r}")
    init = getattr(args, "init", None)
    init = None if init is None else init_files(init)
    if init is not None and init["normalizer"] is None and normalize_kwargs(
            hyperparams.get("normalize")) is not None:
        raise HyperparamsError(
            f"--init {init['model']}: no normaliser comes with this model (none is looked for "
            "beside a bare .zip: it would be a pickle nobody named), and this run normalises "
            "observations: its weights would start on fresh statistics. Pass the model's run "
            "folder or exported policy's folder, which holds its vecnormalize.pkl")
    return {
        "algo": algo,
        "env": env_id,
        "env_kwargs": env_kwargs,
        "seed": seed,
        "n_envs": int(n_envs),
        "vectorization": vectorization,
        "n_timesteps": int(timesteps),
        "hyperparams": hyperparams,
        "hyperparams_file": str(args.hyperparams_file or f"smartcar_gym/config/{algo}.yaml"),
        # the command line's, else the hyperparameters' (a preset's own), else 20,000 and 40
        "eval_freq": _eval_setting(args.eval_freq, hyperparams, "eval_freq", 20_000),
        "eval_episodes": _eval_setting(args.eval_episodes, hyperparams, "eval_episodes", 40),
        # the engine the evaluations run on (None: the training env's); the best model is
        # the one that does best there
        "eval_engine": eval_engine,
        "eval_start": int(timesteps) // 2 if args.eval_start is None else args.eval_start,
        # evaluations in a second process while training goes on (batched runs)
        "eval_async": (hyperparams.get("eval_async", False)
                       if getattr(args, "eval_async", None) is None else args.eval_async),
        "checkpoint_freq": 50_000 if args.checkpoint_freq is None else args.checkpoint_freq,
        "save_replay_buffer": bool(args.save_replay_buffer),
        # the model whose weights and normaliser the run starts from (None: new ones)
        "init": init,
        "device": args.device,
        "versions": _versions(),
        "command": command,
        "created": utc_timestamp(),
        "resumes": [],
    }


def init_files(path: str | os.PathLike) -> dict[str, str | None]:
    """``--init``'s model and normaliser files (``model``, ``normalizer``: absolute paths, the
    normaliser None if the model's place has none); ``HyperparamsError`` if ``path`` names no
    model."""
    from smartcar_gym.agents.models import ModelFilesError, locate_model

    try:
        found = locate_model(path)
    except (ModelFilesError, OSError) as err:
        raise HyperparamsError(f"--init {path}: {err}") from None
    if not found.model.is_file():
        raise HyperparamsError(f"--init {path}: no such model file ({found.model})")
    normalizer = found.normalizer
    return {"model": str(Path(found.model).resolve()),
            "normalizer": None if normalizer is None else str(Path(normalizer).resolve())}


def new_run(parser: argparse.ArgumentParser, args: argparse.Namespace,
            command: str) -> tuple[dict[str, Any], Path]:
    """The config and folder of a new run (exits through ``parser.error`` on bad input).

    A folder whose run never saved a checkpoint or a model (it failed or was killed during
    start-up) is reused: that run's files are removed.
    """
    try:
        config = new_config(args, command)
    except (HyperparamsError, EnvSetupError) as err:
        parser.error(str(err))
    run_dir = args.run_dir or Path("runs") / f"{config['algo']}_{config['env']}_s{config['seed']}"
    problem = output_path_error(run_dir / "config.yaml")
    if problem:
        parser.error(f"--run-dir: {problem}")
    if (run_dir / "config.yaml").exists():
        if saved_models(run_dir, "ckpt_*_steps.zip", "model.zip"):
            parser.error(f"{run_dir} already holds a run; continue it with --resume {run_dir} "
                         "or choose another --run-dir")
        kept = saved_models(run_dir, "best_model.zip")
        if kept:
            parser.error(f"{run_dir} holds a run that saved no checkpoint (it cannot be "
                         f"resumed) but has {kept[0].name}; move that away or choose another "
                         "--run-dir")
        removed = clear_unstarted_run(run_dir)
        print(f"smartcar-train: note: {run_dir} holds a run that never saved a checkpoint or a "
              f"model; starting it again (removed {', '.join(removed)})", file=sys.stderr)
    return config, run_dir


def saved_models(run_dir: Path, *patterns: str) -> list[Path]:
    """Model zips of a run matching ``patterns`` (``ckpt_*`` ones in ``checkpoints/``)."""
    found: list[Path] = []
    for pattern in patterns:
        folder = run_dir / "checkpoints" if pattern.startswith("ckpt_") else run_dir
        found += sorted(folder.glob(pattern))
    return found


def clear_unstarted_run(run_dir: Path) -> list[str]:
    """Remove the files smartcar-train writes in ``run_dir``; returns the names removed."""
    removed = []
    for name in RUN_FILES:
        path = run_dir / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
        else:
            continue
        removed.append(name + ("/" if name in RUN_FOLDERS else ""))
    return removed


def resume_config(parser: argparse.ArgumentParser, args: argparse.Namespace,
                  ) -> tuple[dict[str, Any], Path, Path]:
    """The config, folder and latest checkpoint of the run to resume (``parser.error`` if it
    cannot be resumed)."""
    given = [f"--{k.replace('_id', '').replace('_', '-')}" for k in FIXED_ON_RESUME
             if getattr(args, k) is not None]
    if given:
        parser.error(f"--resume reloads the run's config.yaml; {', '.join(given)} cannot be "
                     "changed (allowed: --timesteps, --eval-freq, --eval-episodes, "
                     "--eval-start, --eval-async, --checkpoint-freq, --device, --torch-threads, "
                     "--no-progress, --save-replay-buffer)")
    run_dir = args.resume
    config_path = run_dir / "config.yaml"
    if not config_path.is_file():
        parser.error(f"--resume: {config_path} not found (is {run_dir} a run folder?)")
    try:
        config = yaml.safe_load(config_path.read_text())
    except yaml.YAMLError as err:
        parser.error(f"--resume: {config_path} is not valid YAML: {err}")
    if not isinstance(config, dict):
        parser.error(f"--resume: {config_path} is not a run config (expected a mapping)")
    for key in ("eval_freq", "eval_episodes", "eval_start", "checkpoint_freq", "eval_async"):
        if getattr(args, key) is not None:
            config[key] = getattr(args, key)
    if args.timesteps is not None:
        config["n_timesteps"] = args.timesteps
    missing = [key for key in REQUIRED_KEYS if key not in config]
    if missing:
        parser.error(f"--resume: {config_path} lacks the key(s) {', '.join(missing)} "
                     "(it was not written by smartcar-train, or was edited)")
    if config["algo"] not in ALGOS or not isinstance(config["hyperparams"], dict):
        parser.error(f"--resume: {config_path}: algo must be one of {', '.join(ALGOS)} and "
                     "hyperparams a mapping")
    config["hyperparams"]["n_timesteps"] = config["n_timesteps"]
    try:
        normalize = normalize_kwargs(config["hyperparams"].get("normalize")) is not None
    except HyperparamsError as err:
        parser.error(f"--resume: {config_path}: {err}")
    checkpoint = find_latest_checkpoint(run_dir, normalize)
    if checkpoint is None:
        parser.error(f"--resume: no complete checkpoint in {run_dir / 'checkpoints'}: the run "
                     "stopped before saving one; start it again with the command that started "
                     "it (it reuses the folder)")
    saved = saved_algo(checkpoint)
    if saved is not None and saved != config["algo"]:
        parser.error(f"--resume: {config_path} says algo: {config['algo']} but {checkpoint} "
                     f"holds a {saved.upper()} model (the config was edited, or the checkpoints "
                     "come from another run)")
    problem = unwritable_folder(run_dir)
    if problem:
        parser.error(f"--resume: {problem}: the run cannot continue there (make it writable, or "
                     "copy the run folder somewhere writable and resume the copy)")
    config["device"] = args.device
    return config, run_dir, checkpoint


def unwritable_folder(run_dir: Path) -> str | None:
    """Why training cannot write into an existing run folder (None if it can): the folder or
    one of its subfolders is not writable."""
    for folder in (run_dir, *(run_dir / name for name in RUN_FOLDERS)):
        if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
            return f"{folder} is not writable"
    return None


def checkpoint_path(run_dir: str | os.PathLike, num_timesteps: int) -> Path:
    """``<run_dir>/checkpoints/ckpt_<steps>_steps.zip``."""
    return Path(run_dir) / "checkpoints" / f"ckpt_{num_timesteps}_steps.zip"


def checkpoint_steps(path: str | os.PathLike) -> int:
    """The step count of a checkpoint from its name ``ckpt_<steps>_steps.zip``."""
    match = CHECKPOINT_RE.match(Path(path).name)
    if match is None:
        raise ValueError(f"{path} is not named like a checkpoint (ckpt_<steps>_steps.zip)")
    return int(match.group(1))


def replay_buffer_path_for(checkpoint: str | os.PathLike) -> Path:
    """The replay buffer saved with a checkpoint: ``ckpt_<steps>_steps_replay_buffer.pkl``."""
    checkpoint = Path(checkpoint)
    return checkpoint.with_name(checkpoint.name.removesuffix(".zip") + "_replay_buffer.pkl")


def checkpoint_info_path_for(checkpoint: str | os.PathLike) -> Path:
    """What a checkpoint records of its run segment: ``ckpt_<steps>_steps.json``."""
    return Path(checkpoint).with_suffix(".json")


def find_latest_checkpoint(run_dir: str | os.PathLike, normalize: bool) -> Path | None:
    """The checkpoint with the most steps (with its VecNormalize file if ``normalize``)."""
    folder = Path(run_dir) / "checkpoints"
    found = []
    for path in folder.glob("ckpt_*_steps.zip") if folder.is_dir() else []:
        match = CHECKPOINT_RE.match(path.name)
        if match and (not normalize or vecnormalize_path_for(path).exists()):
            found.append((int(match.group(1)), path))
    return max(found)[1] if found else None
