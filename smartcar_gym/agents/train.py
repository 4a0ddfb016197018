"""Train PPO, SAC or TD3 on SmartCar-v0 with Stable-Baselines3 (``smartcar-train``).

::

    smartcar-train                                   # PPO with smartcar_gym/config/ppo.yaml
    smartcar-train --algo sac --n-envs 4 --seed 1 --hyperparams learning_rate=1e-3
    smartcar-train --resume runs/ppo_SmartCar-v0_s0 --timesteps 500000

A run folder holds ``config.yaml`` (what ran), ``model.zip`` (+ ``vecnormalize.pkl``),
``checkpoints/``, ``best_model.zip``, ``eval/evaluations.npz``, ``monitor/*.monitor.csv``,
``tb/`` (TensorBoard), ``summary.json`` and ``learning_curve.png``. See ``build_parser``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import shlex
import shutil
import signal
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents.hyperparams import (
    ALGOS,
    HyperparamsError,
    build_algo_kwargs,
    key_value_arg,
    load_hyperparams,
    non_negative_int_arg,
    normalize_kwargs,
    output_path_error,
    positive_int_arg,
    run_int,
)

DEFAULT_ENV_ID = "SmartCar-v0"
# Settings that come from the run's config.yaml when resuming and cannot be changed then.
FIXED_ON_RESUME = ("algo", "env_id", "n_envs", "seed", "hyperparams", "env_kwargs",
                   "hyperparams_file", "run_dir")
# Keys of config.yaml that --resume needs.
REQUIRED_KEYS = ("algo", "env", "seed", "n_envs", "n_timesteps", "hyperparams", "eval_freq",
                 "eval_episodes", "checkpoint_freq")
# What smartcar-train writes in a run folder (removed when a run that never saved a checkpoint
# or a model is started again).
RUN_FOLDERS = ("monitor", "tb", "eval", "checkpoints")
RUN_FILES = ("config.yaml", "summary.json", "learning_curve.png", "vecnormalize.pkl",
             "best_model.json", "best_model_vecnormalize.pkl", *RUN_FOLDERS)
INTERRUPTED_EXIT_CODE = 130  # 128 + SIGINT
TERMINATED_EXIT_CODE = 143  # 128 + SIGTERM


@dataclass
class TrainResult:
    """What a training call did (also written to ``summary.json``)."""

    run_dir: str
    start_timesteps: int
    num_timesteps: int
    wall_time_s: float
    steps_per_s: float
    interrupted: bool
    stop_signal: str | None = None  # "SIGINT" or "SIGTERM" when interrupted
    final_eval: dict[str, Any] | None = None
    best_eval: dict[str, Any] | None = None
    files: list[str] = field(default_factory=list)


# -- command line ---------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-train`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="smartcar-train",
        description="Train an SB3 agent on the smartcar goal-reaching task. Hyperparameters "
                    "come from smartcar_gym/config/<algo>.yaml (rl-baselines3-zoo format) and "
                    "--hyperparams.",
    )
    parser.add_argument("--algo", choices=ALGOS, default=None, help="default: ppo")
    parser.add_argument("--env", dest="env_id", default=None, help=f"default: {DEFAULT_ENV_ID}")
    parser.add_argument("--n-envs", type=positive_int_arg, default=None,
                        help="parallel envs (SubprocVecEnv); default: the file's n_envs, else "
                             "the number of CPUs")
    parser.add_argument("--seed", type=int, default=None, help="default: 0")
    parser.add_argument("--timesteps", type=positive_int_arg, default=None,
                        help="total environment steps (default: the file's n_timesteps); with "
                             "--resume, the new total to reach")
    parser.add_argument("--hyperparams", nargs="+", default=None, type=key_value_arg,
                        metavar="KEY=VALUE", help="override hyperparameters; values are YAML "
                        "(3e-4, true, [64, 64]); policy_kwargs as \"dict(net_arch=[64, 64])\"")
    parser.add_argument("--hyperparams-file", type=Path, default=None,
                        help="a zoo-format YAML instead of the shipped one")
    parser.add_argument("--env-kwargs", nargs="+", default=None, type=key_value_arg,
                        metavar="KEY=VALUE", help="keyword arguments for gym.make (YAML values)")
    parser.add_argument("--run-dir", type=Path, default=None,
                        help="default: runs/<algo>_<env>_s<seed>")
    parser.add_argument("--eval-freq", type=non_negative_int_arg, default=None,
                        help="evaluate every N environment steps (0: never; default 20000)")
    parser.add_argument("--eval-episodes", type=positive_int_arg, default=None,
                        help="episodes per evaluation (default 40)")
    parser.add_argument("--checkpoint-freq", type=non_negative_int_arg, default=None,
                        help="checkpoint every N environment steps (0: only at the end; "
                             "default 50000)")
    parser.add_argument("--save-replay-buffer", action="store_true",
                        help="SAC/TD3: keep the replay buffer with the latest checkpoint, so "
                             "that --resume continues with it (stored in config.yaml)")
    parser.add_argument("--resume", type=Path, default=None, metavar="RUN_DIR",
                        help="continue a run from its last checkpoint (its config.yaml is "
                             "reloaded; step count and normaliser are kept)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--torch-threads", type=positive_int_arg, default=1,
                        help="torch CPU threads (default 1: the env workers need the cores)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser





def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import smartcar_gym

    versions = {"smartcar_gym": smartcar_gym.__version__, "stable_baselines3":
                stable_baselines3.__version__, "torch": torch.__version__,
                "gymnasium": gymnasium.__version__, "python": platform.python_version()}
    return {name: str(version) for name, version in versions.items()}


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def new_config(args: argparse.Namespace, command: str) -> dict[str, Any]:
    """The config of a new run from parsed arguments; raises ``HyperparamsError``."""
    algo = args.algo or "ppo"
    env_id = args.env_id or DEFAULT_ENV_ID
    hyperparams = load_hyperparams(algo, env_id, args.hyperparams_file)
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
    seed = 0 if args.seed is None else args.seed
    return {
        "algo": algo,
        "env": env_id,
        "env_kwargs": dict(args.env_kwargs or []),
        "seed": seed,
        "n_envs": int(n_envs),
        "n_timesteps": int(timesteps),
        "hyperparams": hyperparams,
        "hyperparams_file": str(args.hyperparams_file or f"smartcar_gym/config/{algo}.yaml"),
        "eval_freq": 20_000 if args.eval_freq is None else args.eval_freq,
        "eval_episodes": args.eval_episodes or 40,
        "checkpoint_freq": 50_000 if args.checkpoint_freq is None else args.checkpoint_freq,
        "save_replay_buffer": bool(args.save_replay_buffer),
        "device": args.device,
        "versions": _versions(),
        "command": command,
        "created": _now(),
        "resumes": [],
    }


def discount(hyperparams: dict[str, Any]) -> float:
    """``gamma`` (default 0.99), also used by VecNormalize; raises ``HyperparamsError``."""
    gamma = hyperparams.get("gamma", 0.99)
    if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not 0 <= gamma <= 1:
        raise HyperparamsError(f"gamma must be a number in [0, 1], got {gamma!r}")
    return float(gamma)


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-train``: returns the exit code (130 after Ctrl-C, 143 after SIGTERM, with a
    checkpoint saved; 2 for bad arguments, a bad config or an env or model that cannot be
    made)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    command = shlex.join(["smartcar-train", *(sys.argv[1:] if argv is None else argv)])
    if args.resume is not None:
        config, run_dir, checkpoint = resume_config(parser, args)
    else:
        config, run_dir = new_run(parser, args, command)
        checkpoint = None

    import torch

    torch.set_num_threads(args.torch_threads)
    save_buffer = args.save_replay_buffer or bool(config.get("save_replay_buffer"))
    try:
        result = train(config, run_dir, checkpoint=checkpoint, command=command,
                       progress=not args.no_progress, save_replay_buffer=save_buffer)
    except (RunSetupError, HyperparamsError) as err:
        parser.error(str(err))
    print_summary(result, config)
    if result.interrupted:
        print(f"Interrupted ({result.stop_signal}): checkpoint saved. Continue with: "
              f"smartcar-train --resume {run_dir}", file=sys.stderr)
        if result.stop_signal == "SIGTERM":
            return TERMINATED_EXIT_CODE
        return INTERRUPTED_EXIT_CODE
    return 0


def new_run(parser: argparse.ArgumentParser, args: argparse.Namespace,
            command: str) -> tuple[dict[str, Any], Path]:
    """The config and folder of a new run (exits through ``parser.error`` on bad input).

    A folder whose run never saved a checkpoint or a model (it failed or was killed during
    start-up) is reused: that run's files are removed.
    """
    try:
        config = new_config(args, command)
    except HyperparamsError as err:
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
                     "--checkpoint-freq, --device, --torch-threads, --no-progress, "
                     "--save-replay-buffer)")
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
    for key in ("eval_freq", "eval_episodes", "checkpoint_freq"):
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
    from smartcar_gym.agents.callbacks import find_latest_checkpoint

    checkpoint = find_latest_checkpoint(run_dir, normalize)
    if checkpoint is None:
        parser.error(f"--resume: no complete checkpoint in {run_dir / 'checkpoints'}: the run "
                     "stopped before saving one; start it again with the command that started "
                     "it (it reuses the folder)")
    config["device"] = args.device
    return config, run_dir, checkpoint


# -- training -------------------------------------------------------------------------------
class RunSetupError(ValueError):
    """The envs or the model of a run cannot be made from its config (the message says why)."""


def train(
    config: dict[str, Any],
    run_dir: str | os.PathLike,
    checkpoint: str | os.PathLike | None = None,
    command: str = "",
    progress: bool = True,
    save_replay_buffer: bool | None = None,
    extra_callbacks: Sequence[Any] = (),
) -> TrainResult:
    """Train (or continue from ``checkpoint``) as ``config`` says, writing into ``run_dir``.

    Ctrl-C (SIGINT) or SIGTERM stops training at the next step; a checkpoint and
    ``model.zip`` are saved and the result has ``interrupted=True``. A second signal, or a
    KeyboardInterrupt raised by a callback, stops at once but still saves.

    ``save_replay_buffer`` (SAC/TD3; default: ``config["save_replay_buffer"]``) keeps the
    replay buffer with the checkpoints; the choice is stored in ``config.yaml``. Raises
    ``RunSetupError`` (or ``HyperparamsError``) if the envs or the model cannot be made; the
    failed start then leaves nothing behind (``config.yaml`` is written once both exist).
    """
    from stable_baselines3.common.callbacks import CallbackList

    from smartcar_gym.agents.callbacks import (
        CheckpointCallback,
        ProgressBarCallback,
        StopOnSigint,
        SuccessEvalCallback,
        atomic_write_text,
        checkpoint_steps,
        close_vec_env,
        save_model_atomic,
    )

    run_dir = Path(run_dir)
    algo = config["algo"]
    if save_replay_buffer is not None:
        config["save_replay_buffer"] = bool(save_replay_buffer)
    config.setdefault("save_replay_buffer", False)
    start = 0 if checkpoint is None else checkpoint_steps(checkpoint)
    segment = len(config.get("resumes", [])) + (checkpoint is not None)
    seed = int(config["seed"]) + start  # a resumed run does not replay the first run's goals
    with _undo_on_failure(run_dir, f"seg{segment}_"):
        venv, eval_env = _make_envs(config, run_dir, seed, segment, checkpoint)
        try:
            model = _make_model(config, venv, seed, run_dir / "tb", checkpoint)
            if checkpoint is not None:
                _load_replay_buffer(model, Path(checkpoint), config)
                config["resumes"] = [*config.get("resumes", []), {
                    "from_checkpoint": str(Path(checkpoint).relative_to(run_dir)),
                    "from_timesteps": start, "n_timesteps": int(config["n_timesteps"]),
                    "command": command, "started": _now(),
                }]
            atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
        except BaseException:
            for env in (venv, eval_env):
                if env is not None:
                    close_vec_env(env)
            raise

    target = int(config["n_timesteps"])
    checkpoints = CheckpointCallback(run_dir, int(config["checkpoint_freq"]),
                                     config["save_replay_buffer"])
    callbacks: list[Any] = [checkpoints]
    evaluation = None
    if eval_env is not None:
        evaluation = SuccessEvalCallback(
            eval_env, run_dir / "eval", run_dir / "best_model.zip", int(config["eval_freq"]),
            int(config["eval_episodes"]), eval_seed=int(config["seed"]) + 1_000_000,
        )
        callbacks.append(evaluation)
    bar = ProgressBarCallback(target, evaluation) if progress else None
    if bar is not None:
        callbacks.append(bar)
    callbacks.extend(extra_callbacks)

    aborted = False  # a KeyboardInterrupt went through (second Ctrl-C, or raised by a callback)
    t0 = time.monotonic()
    with StopOnSigint() as stop:
        try:
            if model.num_timesteps < target:
                model.learn(target - model.num_timesteps,
                            callback=CallbackList([stop, *callbacks]),
                            reset_num_timesteps=checkpoint is None, tb_log_name=algo.upper())
        except KeyboardInterrupt:
            aborted = True
        finally:
            if bar is not None:
                bar.close()
        wall = time.monotonic() - t0
        trained = model.num_timesteps - start
        try:
            if checkpoints.model is None:  # learn() did not run (already at the target)
                checkpoints.init_callback(model)
            checkpoints.save()
            save_model_atomic(model, run_dir / "model.zip")
            if evaluation is not None and not (aborted or stop.requested):
                if evaluation.model is None:
                    evaluation.init_callback(model)
                last = evaluation.last_result
                if last is None or last.timesteps != model.num_timesteps:
                    evaluation.evaluate()
        except KeyboardInterrupt:
            aborted = True
        finally:
            for env in (venv, eval_env):
                if env is not None:
                    close_vec_env(env, force=aborted)
        interrupted = aborted or stop.requested
        stop_signal = signal.Signals(stop.signum or signal.SIGINT).name if interrupted else None

    from smartcar_gym.agents.plots import plot_learning_curve

    plot_learning_curve(run_dir)
    result = TrainResult(
        run_dir=str(run_dir), start_timesteps=start, num_timesteps=int(model.num_timesteps),
        wall_time_s=wall, steps_per_s=trained / wall if wall > 0 else 0.0,
        interrupted=interrupted, stop_signal=stop_signal,
        final_eval=None if evaluation is None or evaluation.last_result is None
        else asdict(evaluation.last_result),
        best_eval=_read_json(run_dir / "best_model.json"),
    )
    result.files = sorted(
        {p.name + ("/" if p.is_dir() else "") for p in run_dir.iterdir()} | {"summary.json"}
    )
    atomic_write_text(run_dir / "summary.json", json.dumps(asdict(result), indent=2) + "\n")
    return result


@contextlib.contextmanager
def _undo_on_failure(run_dir: Path, monitor_prefix: str) -> Iterator[None]:
    """If the body raises, remove what a failed start-up created: this segment's Monitor files
    and the folders that did not exist before (only if left empty)."""
    created, folder = [], (run_dir / "monitor").absolute()
    while not folder.exists():
        created.append(folder)  # deepest first
        folder = folder.parent
    try:
        yield
    except BaseException:
        for path in (run_dir / "monitor").glob(f"{monitor_prefix}*.monitor.csv"):
            path.unlink(missing_ok=True)
        for folder in created:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


def _make_envs(config: dict[str, Any], run_dir: Path, seed: int, segment: int,
               checkpoint: str | os.PathLike | None) -> tuple[Any, Any]:
    """The training VecEnv (Monitor files ``seg<segment>_<i>``) and the eval VecEnv (or None),
    wrapped in VecNormalize as the hyperparameters say (statistics from ``checkpoint``)."""
    from smartcar_gym.agents.callbacks import close_vec_env, vecnormalize_path_for
    from smartcar_gym.agents.env_factory import (
        EnvSetupError,
        check_env,
        make_vec_env,
        wrap_normalize,
    )

    env_id, hp = config["env"], config["hyperparams"]
    n_envs, env_kwargs = int(config["n_envs"]), dict(config.get("env_kwargs") or {})
    normalize, gamma = normalize_kwargs(hp.get("normalize")), discount(hp)
    try:
        check_env(env_id, env_kwargs)  # here, not in a worker: a clear error
    except EnvSetupError as err:
        raise RunSetupError(str(err)) from err
    stats = None if checkpoint is None or normalize is None else vecnormalize_path_for(checkpoint)
    venv = make_vec_env(env_id, n_envs, seed=seed, env_kwargs=env_kwargs,
                        monitor_dir=run_dir / "monitor", monitor_prefix=f"seg{segment}_")
    eval_env = None
    try:
        venv = wrap_normalize(venv, normalize, gamma, load_path=stats)
        if config["eval_freq"] > 0:
            n_eval_envs = min(n_envs, int(config["eval_episodes"]), os.cpu_count() or 1)
            eval_env = make_vec_env(env_id, n_eval_envs, env_kwargs=env_kwargs)
            eval_env = wrap_normalize(eval_env, normalize, gamma, training=False)
    except BaseException:
        for env in (venv, eval_env):
            if env is not None:
                close_vec_env(env)
        raise
    return venv, eval_env


def _make_model(config: dict[str, Any], venv: Any, seed: int, tb_dir: Path,
                checkpoint: str | os.PathLike | None) -> Any:
    """A new model from the hyperparameters, or the checkpoint's; ``RunSetupError`` if the
    algorithm refuses them."""
    from smartcar_gym.agents.hyperparams import algo_class

    algo, hp, device = config["algo"], config["hyperparams"], config["device"]
    cls = algo_class(algo)
    if checkpoint is not None:
        try:
            model = cls.load(str(checkpoint), env=venv, device=device, tensorboard_log=str(tb_dir))
        except Exception as err:
            raise RunSetupError(f"cannot load checkpoint {checkpoint}: {err}") from err
        model.set_random_seed(seed)
        return model
    kwargs = build_algo_kwargs(algo, hp, n_actions=venv.action_space.shape[0])
    try:
        return cls(hp.get("policy", "MlpPolicy"), venv, seed=seed, device=device,
                   tensorboard_log=str(tb_dir), verbose=0, **kwargs)
    except (ValueError, TypeError, AssertionError, RuntimeError) as err:
        given = ", ".join(f"{k}={v}" for k, v in hp.items() if k not in ("n_envs", "n_timesteps"))
        raise RunSetupError(
            f"{cls.__name__} refuses its hyperparameters: {type(err).__name__}: {err} "
            f"(hyperparameters: {given}; set in {config.get('hyperparams_file', 'the file')} "
            "or with --hyperparams)"
        ) from err


def _load_replay_buffer(model: Any, checkpoint: Path, config: dict[str, Any]) -> None:
    """Load the replay buffer saved with ``checkpoint`` (SAC/TD3); warn if there is none."""
    from smartcar_gym.agents.callbacks import replay_buffer_path_for

    if not hasattr(model, "load_replay_buffer"):
        return
    path = replay_buffer_path_for(checkpoint)
    if path.is_file():
        model.load_replay_buffer(str(path))
        return
    others = sorted(p.name for p in checkpoint.parent.glob("*replay_buffer.pkl"))
    if others:
        why = f"{', '.join(others)} is not the buffer of {checkpoint.name}, so it is not used"
    elif config.get("save_replay_buffer"):
        why = f"no replay buffer was saved with {checkpoint.name}"
    else:
        why = "the run was started without --save-replay-buffer"
    print(f"smartcar-train: warning: {config['algo'].upper()} resumes with an empty replay "
          f"buffer: {why}", file=sys.stderr)


def _read_json(path: Path) -> dict[str, Any] | None:
    return json.loads(path.read_text()) if path.exists() else None


def print_summary(result: TrainResult, config: dict[str, Any]) -> None:
    """A one-screen table of the run: steps, time, speed, evaluation, files."""
    from rich.console import Console
    from rich.table import Table

    status = "interrupted" if result.interrupted else "done"
    table = Table(title=f"{config['algo'].upper()} on {config['env']} (seed {config['seed']}, "
                        f"{config['n_envs']} envs): {status}")
    table.add_column("", style="bold")
    table.add_column("")
    steps = f"{result.num_timesteps:,}"
    if result.start_timesteps:
        steps += f" (resumed at {result.start_timesteps:,})"
    table.add_row("environment steps", steps)
    table.add_row("wall time", f"{result.wall_time_s / 60:.1f} min ({result.wall_time_s:.0f} s)")
    table.add_row("steps/s", f"{result.steps_per_s:,.0f} (incl. evaluation)")
    for name, ev in (("final eval", result.final_eval), ("best eval", result.best_eval)):
        if ev:
            table.add_row(name, f"success {ev['success_rate']:.0%}, return "
                                f"{ev['mean_reward']:.1f}, final distance "
                                f"{ev['mean_final_distance']:.3f} m (at {ev['timesteps']:,} steps)")
    table.add_row("run folder", result.run_dir)
    table.add_row("files", ", ".join(result.files))
    Console().print(table)


if __name__ == "__main__":
    sys.exit(main())
