"""The RLlib PPO recipe: one large run whose sampling is spread over many EnvRunners.

::

    python -m smartcar_gym.scale.rllib --env-runners 2 --iterations 50 --out runs/rllib
    python -m smartcar_gym.scale.rllib --address auto --env-runners 62 --out /shared/rllib

Or from Python (the same steps)::

    from smartcar_gym.scale import rllib
    config = rllib.ppo_config(num_env_runners=2)
    algo = rllib.build(config)          # registers the env, checks the CPUs, builds
    result = algo.train()

The env comes from ``rllib_env.make_env`` (in the installed package, so every EnvRunner can
import it; each env its own pybullet client). ``check_resources`` refuses a config that
asks for more CPUs than the cluster has: Ray would otherwise wait forever, silently. RLlib's
PPO is not Stable-Baselines3's: its defaults, connectors and results differ (docs/scaling.md).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import inspect
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from smartcar_gym.agents.cli_args import key_value_arg, non_negative_int_arg, positive_int_arg
from smartcar_gym.scale.ray_session import (
    RayUnavailableError,
    ResourceError,
    check_cpus,
    ray_session,
    require_ray,
)
from smartcar_gym.scale.rllib_env import ENV_ID_KEY, ENV_NAME, register

PROG = "python -m smartcar_gym.scale.rllib"


@functools.cache
def success_rate_callback() -> type:
    """An RLlib callback class logging ``success_rate`` (the env's ``is_success`` at each
    episode's end) beside the returns, in the training and the evaluation results. (Made on
    first use so that this module imports without Ray; Ray ships the class by value.)"""
    from ray.rllib.callbacks.callbacks import RLlibCallback

    class SuccessRate(RLlibCallback):
        def on_episode_end(self, *, episode: Any, metrics_logger: Any = None,
                           **kwargs: Any) -> None:
            info = episode.get_infos(-1) or {}
            if metrics_logger is not None:
                metrics_logger.log_value("success_rate", float(bool(info.get("is_success"))),
                                         reduce="mean", window=100)

    return SuccessRate


def ppo_config(num_env_runners: int = 2, envs_per_runner: int = 1,
               env_kwargs: dict[str, Any] | None = None, *, env_id: str = "SmartCar-v0",
               train_batch_size: int = 4000, minibatch_size: int = 128, num_epochs: int = 10,
               lr: float = 3e-4, seed: int = 0, evaluation_interval: int = 10,
               evaluation_episodes: int = 10, sample_timeout_s: float = 120.0) -> Any:
    """RLlib PPO on the smartcar env (new API stack, torch, learner in the driver).

    ``num_env_runners`` sampling actors of 1 CPU each (0: sample in the driver), each with
    ``envs_per_runner`` envs stepped in turn. Evaluation (deterministic actions) runs in the
    driver every ``evaluation_interval`` iterations (0: never). Returns a ``PPOConfig``.
    """
    from ray.rllib.algorithms.ppo import PPOConfig

    config = (
        PPOConfig()
        .environment(ENV_NAME, env_config={ENV_ID_KEY: env_id, **(env_kwargs or {})})
        .env_runners(num_env_runners=num_env_runners, num_envs_per_env_runner=envs_per_runner,
                     num_cpus_per_env_runner=1, sample_timeout_s=sample_timeout_s)
        .learners(num_learners=0)
        .training(train_batch_size_per_learner=train_batch_size, minibatch_size=minibatch_size,
                  num_epochs=num_epochs, lr=lr)
        .callbacks(success_rate_callback())
        .debugging(seed=seed)
    )
    if evaluation_interval > 0:
        config = config.evaluation(
            evaluation_interval=evaluation_interval, evaluation_num_env_runners=0,
            evaluation_duration=evaluation_episodes, evaluation_duration_unit="episodes",
            evaluation_config={"explore": False})
    return config


def check_resources(config: Any) -> None:
    """Refuse a config whose actors (EnvRunners, evaluation EnvRunners, learners) need more
    CPUs than the connected cluster has; RLlib's own accounting
    (``default_resource_request``) says what each needs. The driver, which builds the
    algorithm, holds no Ray CPU."""
    from ray.rllib.algorithms.ppo import PPO

    bundles = PPO.default_resource_request(config).bundles[1:]  # [0]: the driver (Tune only)
    requests = [float(b.get("CPU", 0)) for b in bundles if b.get("CPU", 0) > 0]
    if requests:
        check_cpus(requests, f"{config.num_env_runners} EnvRunner(s) of "
                             f"{config.num_cpus_per_env_runner} CPU, "
                             f"{config.evaluation_num_env_runners} evaluation EnvRunner(s) and "
                             f"{config.num_learners} learner(s)",
                   "num_env_runners (--env-runners)")


def build(config: Any, log_dir: str | Path | None = None) -> Any:
    """Register the env, check the CPUs and build the algorithm. Ray 2.50 logs an algorithm's
    results (JSON, CSV, TensorBoard) to ``~/ray_results``: to ``log_dir`` when given. (Ray 2.60
    logs nothing there, and ``build_algo`` takes no logger.)"""
    register()
    check_resources(config)
    if log_dir is None or "logger_creator" not in inspect.signature(config.build_algo).parameters:
        return config.build_algo()
    from ray.tune.logger import UnifiedLogger

    Path(log_dir).mkdir(parents=True, exist_ok=True)
    return config.build_algo(logger_creator=lambda algo_config: UnifiedLogger(
        algo_config, str(log_dir), loggers=None))


def summarize(result: dict[str, Any]) -> dict[str, Any]:
    """The numbers of an iteration's result that say how training goes."""
    runners = result.get("env_runners", {})
    evaluation = result.get("evaluation", {}).get("env_runners", {})
    return {
        "iteration": result.get("training_iteration"),
        "env_steps": runners.get("num_env_steps_sampled_lifetime"),
        "episode_return_mean": runners.get("episode_return_mean"),
        "success_rate": runners.get("success_rate"),
        "eval_return_mean": evaluation.get("episode_return_mean"),
        "eval_success_rate": evaluation.get("success_rate"),
        "time_s": result.get("time_this_iter_s"),
    }


def run(config: Any, iterations: int, out: str | Path, checkpoint_every: int = 10,
        restore: str | Path | None = None) -> list[dict[str, Any]]:
    """Train ``iterations`` iterations (after restoring the weights and state of ``restore``),
    saving ``<out>/checkpoint_<iteration>`` every ``checkpoint_every`` and at the end, and
    ``<out>/progress.jsonl`` (one ``summarize`` line per iteration)."""
    out = Path(out).absolute()
    out.mkdir(parents=True, exist_ok=True)
    algo = build(config, out / "logs")
    rows = []
    try:
        if restore is not None:
            algo.restore_from_path(str(Path(restore).absolute()))
        for i in range(iterations):
            row = summarize(algo.train())
            rows.append(row)
            with open(out / "progress.jsonl", "a") as f:
                f.write(json.dumps(row) + "\n")
            if (i + 1) % max(checkpoint_every, 1) == 0 or i + 1 == iterations:
                algo.save_to_path(str(out / f"checkpoint_{row['iteration']:06d}"))
    finally:
        algo.stop()
        with contextlib.suppress(OSError):  # the empty folder Ray 2.6x makes in ~/ray_results
            os.rmdir(algo.logdir)
    return rows


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description="Train RLlib PPO on the smartcar "
                                     "env with many EnvRunners (docs/scaling.md).")
    parser.add_argument("--out", type=Path, required=True, help="checkpoints and progress")
    parser.add_argument("--env-runners", type=non_negative_int_arg, default=2,
                        help="sampling actors, 1 CPU each (0: sample in the driver)")
    parser.add_argument("--envs-per-runner", type=positive_int_arg, default=1)
    parser.add_argument("--iterations", type=positive_int_arg, default=10)
    parser.add_argument("--train-batch", type=positive_int_arg, default=4000,
                        help="env steps per iteration")
    parser.add_argument("--minibatch", type=positive_int_arg, default=128)
    parser.add_argument("--epochs", type=positive_int_arg, default=10)
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--seed", type=non_negative_int_arg, default=0)
    parser.add_argument("--eval-interval", type=non_negative_int_arg, default=10,
                        help="evaluate every N iterations (0: never)")
    parser.add_argument("--eval-episodes", type=positive_int_arg, default=10)
    parser.add_argument("--checkpoint-every", type=positive_int_arg, default=10)
    parser.add_argument("--env-kwargs", nargs="+", type=key_value_arg, default=None,
                        metavar="KEY=VALUE", help="keyword arguments of the env (YAML values)")
    parser.add_argument("--restore", type=Path, default=None, metavar="CHECKPOINT",
                        help="continue from a checkpoint_<n> folder of an earlier run")
    parser.add_argument("--num-cpus", type=positive_int_arg, default=None,
                        help="CPUs of the local Ray instance (default: all)")
    parser.add_argument("--address", default=None, help="a running Ray cluster")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Train; 2 for bad input (one line on stderr)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.address is not None and args.num_cpus is not None:
        parser.error("--num-cpus is for a new local Ray instance; not with --address")
    try:
        require_ray("ray.rllib")
    except RayUnavailableError as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return 2
    if args.restore is not None and not (args.restore / "rllib_checkpoint.json").is_file():
        parser.error(f"--restore: {args.restore} is not an RLlib checkpoint folder "
                     "(no rllib_checkpoint.json)")
    config = ppo_config(args.env_runners, args.envs_per_runner, dict(args.env_kwargs or []),
                        train_batch_size=args.train_batch, minibatch_size=args.minibatch,
                        num_epochs=args.epochs, lr=args.lr, seed=args.seed,
                        evaluation_interval=args.eval_interval,
                        evaluation_episodes=args.eval_episodes)
    try:
        with ray_session(args.address, args.num_cpus):
            for row in run(config, args.iterations, args.out, args.checkpoint_every,
                           args.restore):
                print(json.dumps(row))
    except (RayUnavailableError, ResourceError) as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
