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
import json
import os
import platform
import shlex
import sys
import time
from collections.abc import Sequence
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
    positive_int_arg,
)

DEFAULT_ENV_ID = "SmartCar-v0"
# Settings that come from the run's config.yaml when resuming and cannot be changed then.
FIXED_ON_RESUME = ("algo", "env_id", "n_envs", "seed", "hyperparams", "env_kwargs",
                   "hyperparams_file", "run_dir")
INTERRUPTED_EXIT_CODE = 130


@dataclass
class TrainResult:
    """What a training call did (also written to ``summary.json``)."""

    run_dir: str
    start_timesteps: int
    num_timesteps: int
    wall_time_s: float
    steps_per_s: float
    interrupted: bool
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
                        help="SAC/TD3: keep the replay buffer with the checkpoints for --resume")
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
    n_envs = args.n_envs or hyperparams.get("n_envs") or os.cpu_count() or 1
    timesteps = args.timesteps or hyperparams.get("n_timesteps")
    if not timesteps:
        raise HyperparamsError(f"no n_timesteps for {env_id} in the {algo} hyperparameters; "
                               "pass --timesteps")
    hyperparams["n_envs"], hyperparams["n_timesteps"] = int(n_envs), int(timesteps)
    hyperparams.setdefault("policy", "MlpPolicy")
    normalize_kwargs(hyperparams.get("normalize"))  # validate early
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
        "device": args.device,
        "versions": _versions(),
        "command": command,
        "created": _now(),
        "resumes": [],
    }


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-train``: returns the exit code (130 after Ctrl-C, with a checkpoint saved)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    command = shlex.join(["smartcar-train", *(sys.argv[1:] if argv is None else argv)])

    if args.resume is not None:
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
        config = yaml.safe_load(config_path.read_text())
        normalize = normalize_kwargs(config["hyperparams"].get("normalize")) is not None
        from smartcar_gym.agents.callbacks import find_latest_checkpoint

        checkpoint = find_latest_checkpoint(run_dir, normalize)
        if checkpoint is None:
            parser.error(f"--resume: no complete checkpoint in {run_dir / 'checkpoints'}")
        for key in ("eval_freq", "eval_episodes", "checkpoint_freq"):
            if getattr(args, key) is not None:
                config[key] = getattr(args, key)
        if args.timesteps is not None:
            config["n_timesteps"] = config["hyperparams"]["n_timesteps"] = args.timesteps
        config["device"] = args.device
    else:
        try:
            config = new_config(args, command)
        except HyperparamsError as err:
            parser.error(str(err))
        default_dir = Path("runs") / f"{config['algo']}_{config['env']}_s{config['seed']}"
        run_dir = args.run_dir or default_dir
        if (run_dir / "config.yaml").exists():
            parser.error(f"{run_dir} already holds a run; continue it with --resume {run_dir} "
                         "or choose another --run-dir")
        checkpoint = None

    import torch

    torch.set_num_threads(args.torch_threads)
    result = train(config, run_dir, checkpoint=checkpoint, command=command,
                   progress=not args.no_progress, save_replay_buffer=args.save_replay_buffer)
    print_summary(result, config)
    if result.interrupted:
        print(f"Interrupted: checkpoint saved. Continue with: smartcar-train --resume {run_dir}",
              file=sys.stderr)
        return INTERRUPTED_EXIT_CODE
    return 0


# -- training -------------------------------------------------------------------------------
def train(
    config: dict[str, Any],
    run_dir: str | os.PathLike,
    checkpoint: str | os.PathLike | None = None,
    command: str = "",
    progress: bool = True,
    save_replay_buffer: bool = False,
    extra_callbacks: Sequence[Any] = (),
) -> TrainResult:
    """Train (or continue from ``checkpoint``) as ``config`` says, writing into ``run_dir``.

    Ctrl-C (SIGINT) stops training at the next step; a checkpoint and ``model.zip`` are saved
    and the result has ``interrupted=True``. A second Ctrl-C, or a KeyboardInterrupt raised by
    a callback, stops at once but still saves.
    """
    from stable_baselines3.common.callbacks import CallbackList

    from smartcar_gym.agents.callbacks import (
        CHECKPOINT_RE,
        CheckpointCallback,
        ProgressBarCallback,
        StopOnSigint,
        SuccessEvalCallback,
        atomic_write_text,
        close_vec_env,
        save_model_atomic,
        vecnormalize_path_for,
    )
    from smartcar_gym.agents.env_factory import make_vec_env, wrap_normalize
    from smartcar_gym.agents.hyperparams import algo_class

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    algo, env_id, hp = config["algo"], config["env"], config["hyperparams"]
    n_envs, env_kwargs = int(config["n_envs"]), dict(config.get("env_kwargs") or {})
    normalize = normalize_kwargs(hp.get("normalize"))
    gamma = float(hp.get("gamma", 0.99))
    start = 0
    if checkpoint is not None:
        start = int(CHECKPOINT_RE.match(Path(checkpoint).name).group(1))
        config.setdefault("resumes", []).append({
            "from_checkpoint": str(Path(checkpoint).relative_to(run_dir)),
            "from_timesteps": start, "n_timesteps": int(config["n_timesteps"]),
            "command": command, "started": _now(),
        })
    atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    segment = len(config.get("resumes", []))
    seed = int(config["seed"]) + start  # a resumed run does not replay the first run's goals

    venv = make_vec_env(env_id, n_envs, seed=seed, env_kwargs=env_kwargs,
                        monitor_dir=run_dir / "monitor", monitor_prefix=f"seg{segment}_")
    if checkpoint is not None and normalize is not None:
        venv = wrap_normalize(venv, normalize, gamma, load_path=vecnormalize_path_for(checkpoint))
    else:
        venv = wrap_normalize(venv, normalize, gamma)
    eval_env = None
    if config["eval_freq"] > 0:
        n_eval_envs = min(n_envs, int(config["eval_episodes"]), os.cpu_count() or 1)
        eval_env = wrap_normalize(make_vec_env(env_id, n_eval_envs, env_kwargs=env_kwargs),
                                  normalize, gamma, training=False)

    cls = algo_class(algo)
    tb_dir = str(run_dir / "tb")
    if checkpoint is None:
        kwargs = build_algo_kwargs(algo, hp, n_actions=venv.action_space.shape[0])
        model = cls(hp.get("policy", "MlpPolicy"), venv, seed=seed, device=config["device"],
                    tensorboard_log=tb_dir, verbose=0, **kwargs)
    else:
        model = cls.load(str(checkpoint), env=venv, device=config["device"],
                         tensorboard_log=tb_dir)
        model.set_random_seed(seed)
        buffer = Path(checkpoint).parent / "replay_buffer.pkl"
        if buffer.exists() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(str(buffer))

    target = int(config["n_timesteps"])
    checkpoints = CheckpointCallback(run_dir, int(config["checkpoint_freq"]), save_replay_buffer)
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

    from smartcar_gym.agents.plots import plot_learning_curve

    plot_learning_curve(run_dir)
    result = TrainResult(
        run_dir=str(run_dir), start_timesteps=start, num_timesteps=int(model.num_timesteps),
        wall_time_s=wall, steps_per_s=trained / wall if wall > 0 else 0.0,
        interrupted=interrupted,
        final_eval=None if evaluation is None or evaluation.last_result is None
        else asdict(evaluation.last_result),
        best_eval=_read_json(run_dir / "best_model.json"),
    )
    result.files = sorted(
        {p.name + ("/" if p.is_dir() else "") for p in run_dir.iterdir()} | {"summary.json"}
    )
    atomic_write_text(run_dir / "summary.json", json.dumps(asdict(result), indent=2) + "\n")
    return result


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
