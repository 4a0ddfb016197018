"""Train PPO, SAC or TD3 on SmartCar-v0 with Stable-Baselines3 (``smartcar-train``).

::

    smartcar-train                                   # PPO with smartcar_gym/config/ppo.yaml
    smartcar-train --algo sac --n-envs 4 --seed 1 --hyperparams learning_rate=1e-3
    smartcar-train --resume runs/ppo_SmartCar-v0_s0 --timesteps 500000

A run folder holds ``config.yaml`` (what ran), ``model.zip`` (+ ``vecnormalize.pkl``),
``checkpoints/``, ``best_model.zip``, ``eval/evaluations.npz``, ``monitor/*.monitor.csv``,
``tb/`` (TensorBoard), ``summary.json`` and ``learning_curve.png``. See ``build_parser``;
``runs`` makes and checks the folder, ``training`` (the library this command calls) trains.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from smartcar_gym.agents import require_train_extra
from smartcar_gym.agents.cli_args import key_value_arg, non_negative_int_arg, positive_int_arg
from smartcar_gym.agents.hyperparams import ALGOS, HyperparamsError
from smartcar_gym.agents.process_start import run_command
from smartcar_gym.agents.runs import DEFAULT_ENV_ID, new_run, resume_config
from smartcar_gym.agents.training import RunSetupError, TrainResult, train
from smartcar_gym.agents.vec_envs import VECTORIZATIONS
from smartcar_gym.sim.engines import add_engine_argument, engine_names

FAILED_EXIT_CODE = 1  # the run stopped on an error (a full disk...)
INTERRUPTED_EXIT_CODE = 130  # 128 + SIGINT
TERMINATED_EXIT_CODE = 143  # 128 + SIGTERM


# -- command line ---------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-train`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="smartcar-train",
        description="Train an SB3 agent on the smartcar goal-reaching task. Hyperparameters "
                    "come from smartcar_gym/config/<algo>.yaml (rl-baselines3-zoo format) and "
                    "--hyperparams.",
        epilog="Checkpoints (.zip) and normaliser and replay-buffer files (.pkl) are pickles: "
               "loading one runs the code it holds. --resume loads those of the run folder it "
               "names, so resume only runs that you trust. Exit codes: 2 for bad input, 1 when "
               "the run stops on an error (one line; the last checkpoint is kept), 130/143 "
               "after Ctrl-C/SIGTERM (a checkpoint is saved).",
    )
    parser.add_argument("--algo", choices=ALGOS, default=None, help="default: ppo")
    parser.add_argument("--env", dest="env_id", default=None, help=f"default: {DEFAULT_ENV_ID}")
    parser.add_argument("--n-envs", type=positive_int_arg, default=None,
                        help="parallel envs (SubprocVecEnv); default: the file's n_envs, else "
                             "the number of CPUs")
    parser.add_argument("--vectorization", choices=VECTORIZATIONS, default=None,
                        help="subproc (default): one process per env (SubprocVecEnv); batched: "
                             "all n-envs cars in this process through the env's "
                             "vector_entry_point (SmartCarSim-v0: numpy arrays; --engine "
                             "mujoco: MuJoCo in C; --engine planar: the planar model in numpy "
                             "arrays; pybullet: a loop of single envs), with the "
                             "hyperparameters' <env>-batched-<engine>, else <env>-batched entry "
                             "if it has one")
    parser.add_argument("--seed", type=non_negative_int_arg, default=None,
                        help="an integer >= 0 (default: 0)")
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
    add_engine_argument(parser)
    parser.add_argument("--eval-engine", choices=engine_names(), default=None,
                        help="run the evaluations (which pick the best model) on this engine "
                             "instead of the training env's, e.g. train on planar, evaluate on "
                             "pybullet (default: the hyperparameters' eval_engine, else the "
                             "training engine)")
    parser.add_argument("--eval-async", action=argparse.BooleanOptionalAction, default=None,
                        help="run the evaluations in a second process while training goes on "
                             "(with --vectorization batched; default: the hyperparameters' "
                             "eval_async, else no)")
    parser.add_argument("--run-dir", type=Path, default=None,
                        help="default: runs/<algo>_<env>_s<seed>")
    parser.add_argument("--eval-freq", type=non_negative_int_arg, default=None,
                        help="evaluate every N environment steps (0: never; default: the "
                             "hyperparameters' eval_freq, else 20000)")
    parser.add_argument("--eval-episodes", type=positive_int_arg, default=None,
                        help="episodes per evaluation (default: the hyperparameters' "
                             "eval_episodes, else 40)")
    parser.add_argument("--eval-start", type=non_negative_int_arg, default=None,
                        help="first evaluation at the first multiple of --eval-freq from N "
                             "steps on (default: half the run's steps; a policy that still "
                             "times out makes early evaluations long, and the best model comes "
                             "late)")
    parser.add_argument("--checkpoint-freq", type=non_negative_int_arg, default=None,
                        help="checkpoint every N environment steps (0: only at the end; "
                             "default 50000)")
    parser.add_argument("--save-replay-buffer", action="store_true",
                        help="SAC/TD3: keep the replay buffer with the latest checkpoint, so "
                             "that --resume continues with it (stored in config.yaml)")
    parser.add_argument("--resume", type=Path, default=None, metavar="RUN_DIR",
                        help="continue a run from its last checkpoint (its config.yaml is "
                             "reloaded; step count and normaliser are kept)")
    parser.add_argument("--init", type=Path, default=None, metavar="MODEL",
                        help="a new run starting from this model's weights and normaliser "
                             "statistics (a run folder or exported policy's folder; a model "
                             ".zip alone where the run does not normalise; a pickle: only one "
                             "you trust); its network and spaces must be the run's")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--torch-threads", type=positive_int_arg, default=1,
                        help="torch CPU threads (default 1: the env workers need the cores)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-train``: returns the exit code (130 after Ctrl-C, 143 after SIGTERM, with a
    checkpoint saved; 2 for bad arguments, a bad config or an env or model that cannot be
    made; 1 when the run stops on another error, with a one-line message and the traceback in
    ``<run>/error.log``)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    require_train_extra("smartcar-train")
    command = shlex.join(["smartcar-train", *(sys.argv[1:] if argv is None else argv)])
    if args.engine is not None:  # one of the env's kwargs, stored with the run
        if args.resume is not None:
            parser.error("--resume reloads the run's config.yaml (its engine); --engine cannot "
                         "be given with it")
        args.env_kwargs = [*(args.env_kwargs or []), ("engine", args.engine)]
    if args.resume is not None and args.init is not None:
        parser.error("--init starts a new run from a model; --resume continues a run: give one")
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
    except Exception as err:  # whatever stopped the run: one line, not a traceback
        print(f"smartcar-train: error: {failure_message(err, config, run_dir)}", file=sys.stderr)
        return FAILED_EXIT_CODE
    print_summary(result, config)
    if result.interrupted:
        print(f"Interrupted ({result.stop_signal}): checkpoint saved. Continue with: "
              f"smartcar-train --resume {run_dir}", file=sys.stderr)
        if result.stop_signal == "SIGTERM":
            return TERMINATED_EXIT_CODE
        return INTERRUPTED_EXIT_CODE
    return 0


def failure_message(err: BaseException, config: dict[str, Any], run_dir: Path) -> str:
    """One line on a run that stopped on ``err``: what failed, the last checkpoint kept, how to
    continue. The traceback goes to ``<run_dir>/error.log`` if it can be written."""
    import traceback

    from smartcar_gym.agents.hyperparams import normalize_kwargs
    from smartcar_gym.agents.runs import checkpoint_steps, find_latest_checkpoint

    what = str(err) or type(err).__name__
    if isinstance(err, OSError) and err.filename:
        what = f"{err.strerror or err}: {err.filename}"
    message = f"the run stopped: {type(err).__name__}: {what}"
    try:
        normalize = normalize_kwargs(config["hyperparams"].get("normalize")) is not None
    except (HyperparamsError, KeyError, AttributeError):
        normalize = True
    checkpoint = find_latest_checkpoint(run_dir, normalize)
    if checkpoint is not None:
        message += (f"; the last checkpoint, {checkpoint} ({checkpoint_steps(checkpoint):,} "
                    f"steps), is intact: continue with smartcar-train --resume {run_dir}")
    else:
        message += "; no checkpoint was saved"
    log = run_dir / "error.log"
    try:
        log.write_text("".join(traceback.format_exception(err)))
        message += f" (traceback in {log})"
    except OSError:
        pass
    return message


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
    if result.final_eval_s >= 0.5:
        table.add_row("then", f"{result.final_eval_s:.0f} s to the last evaluation")
    for name, ev in (("final eval", result.final_eval), ("best eval", result.best_eval)):
        if ev:
            table.add_row(name, f"success {ev['success_rate']:.0%}, return "
                                f"{ev['mean_reward']:.1f}, final distance "
                                f"{ev['mean_final_distance']:.3f} m (at {ev['timesteps']:,} steps)")
    table.add_row("run folder", result.run_dir)
    table.add_row("files", ", ".join(result.files))
    Console().print(table)


def run() -> NoReturn:
    """The ``smartcar-train`` command's process: ``main`` through ``process_start.run_command``
    (the process set up, then ended without Python's teardown)."""
    run_command(main)


if __name__ == "__main__":
    run()
