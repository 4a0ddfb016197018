"""Evaluate a trained policy on seeded episodes: metrics, JSON, video and trajectory plot.

``main`` is ``smartcar-eval``::

    smartcar-eval --pretrained --episodes 100 --n-envs 4 --video smartcar.gif --plot paths.png
    smartcar-eval --model runs/ppo_SmartCar-v0_s0/model.zip --json results.json
    smartcar-eval --model logs/ppo/SmartCar-v0_1      # an rl-baselines3-zoo run folder
    smartcar-eval --model model.zip --engine mujoco --vectorization batched --fail-under 95
    smartcar-eval --model policy.onnx --engine planar --minari smartcar/default-planar-v0

The episodes are run by ``episodes.evaluate_policy_episodes`` (episode ``i`` uses seed
``seed + i``; the results do not depend on ``n_envs``); ``smartcar_gym.policy.Policy.load``
finds and loads the model and the normaliser (VecNormalize statistics, a pickle) that may be
loaded with it (``models`` says which). ``--vectorization batched`` runs the same episodes on
the cars of one vector env (``episodes.evaluate_batched_episodes``); ``--fail-under`` and
``--max-final-distance`` are pass marks (exit status 1 when one is missed: docs/ci.md).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from smartcar_gym.agents import EVAL_MODULES, require_train_extra
from smartcar_gym.agents.cli_args import (
    distance_arg,
    key_value_arg,
    non_negative_int_arg,
    percent_arg,
    positive_int_arg,
)
from smartcar_gym.agents.env_factory import EnvSetupError, check_env
from smartcar_gym.agents.episodes import (
    DEFAULT_BATCH,
    ObservationShapeError,
    evaluate_batched_episodes,
    evaluate_policy_episodes,
)
from smartcar_gym.agents.eval_outputs import (
    check_outputs,
    close_recorders,
    count,
    open_recorders,
    serve_until_interrupted,
)
from smartcar_gym.agents.hyperparams import ALGOS
from smartcar_gym.agents.models import PRETRAINED_MODEL, PRETRAINED_POLICIES, load_model
from smartcar_gym.agents.policies import DEFAULT_ENV_ID, Policy, PolicyError
from smartcar_gym.agents.process_start import run_command
from smartcar_gym.agents.random_policy import RandomPolicy
from smartcar_gym.agents.records import summarize
from smartcar_gym.agents.references import reference_scores
from smartcar_gym.agents.vec_envs import VECTORIZATIONS
from smartcar_gym.agents.video import record_video
from smartcar_gym.checks import distinct_figure
from smartcar_gym.datasets.eval_options import (
    add_minari_arguments,
    check_minari_arguments,
    minari_steps,
    write_minari,
)
from smartcar_gym.runtime.onnx_policy import is_onnx_path
from smartcar_gym.sim.engines import DEFAULT_ENGINE, add_engine_argument

__all__ = ["build_parser", "check_outputs", "distance_arg", "evaluate_policy_episodes",
           "load_model", "main", "percent_arg", "summarize"]

TRUST_NOTE = ("SB3 model zips and VecNormalize files are pickles: loading one runs the code it "
              "holds, so use only files from a source you trust.")


# -- command line -----------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-eval`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="smartcar-eval",
        description="Evaluate a trained smartcar policy on seeded episodes (episode i uses "
                    "seed SEED+i); prints success rate, return, time to goal, final distance "
                    "and odometry error.",
        epilog=f"{TRUST_NOTE} A normaliser is loaded only from --vecnormalize or from the "
               "model's own place: a smartcar-train run folder (model.zip with "
               "vecnormalize.pkl, <name>.zip with <name>_vecnormalize.pkl), an exported "
               "policy's folder, or an rl-baselines3-zoo run folder (<env>/vecnormalize.pkl "
               "when <env>/config.yml says normalize). Which one was loaded, or that none was, "
               "is printed and written to --json.",
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--model", type=Path, help="a model .zip, or a run folder (its final "
                        "model) of smartcar-train or rl-baselines3-zoo; the run's config and "
                        "normaliser are found from the folder's layout; or an .onnx file of "
                        "smartcar-export")
    source.add_argument("--pretrained", nargs="?", const="default", metavar="NAME",
                        choices=tuple(PRETRAINED_POLICIES), help="a policy shipped with the "
                        "package: default (the one --pretrained alone names), robust "
                        "(trained with randomize=default), nav (SAC on SmartCarNav-v0), ros "
                        "(SmartCarArrive-v0), mujoco (trained with engine=mujoco), barn (PPO "
                        "on SmartCarBARN-v0 without a map; smartcar-bench barn runs its "
                        "benchmark) or barn-known (the same on the known map)")
    source.add_argument("--random", action="store_true", help="uniform random actions, seeded "
                        "with --seed (a baseline)")
    parser.add_argument("--algo", choices=ALGOS, help="algorithm of --model (default: from the "
                        "run's config.yaml)")
    parser.add_argument("--env", dest="env_id", help="env id (default: the run's, else "
                        f"{DEFAULT_ENV_ID})")
    parser.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                        type=key_value_arg, help="gym.make keyword arguments (YAML values); "
                        "added to the run's own env kwargs")
    parser.add_argument("--vecnormalize", type=Path, metavar="FILE", help="VecNormalize "
                        "statistics to load (a pickle: only from a trusted source; default: the "
                        "ones the model's run folder assigns to it)")
    add_engine_argument(parser, what="the evaluation's")
    parser.add_argument("--episodes", type=positive_int_arg, default=100)
    parser.add_argument("--n-envs", type=positive_int_arg, default=None,
                        help="envs run in parallel: worker processes when > 1 (default 1), or "
                             "with --vectorization batched the cars of the batch (default "
                             f"{DEFAULT_BATCH})")
    parser.add_argument("--vectorization", choices=VECTORIZATIONS, default="subproc",
                        help="subproc (default): single envs, in worker processes when "
                             "--n-envs > 1; batched: --n-envs cars of the id's "
                             "vector_entry_point in this process (the MuJoCo batches in C, the "
                             "planar batches in numpy arrays, the numpy SmartCarSim-v0 batch, a "
                             "loop of single envs elsewhere), all cars' "
                             "actions from one predict call per step; the same episodes")
    parser.add_argument("--record-episodes", type=positive_int_arg, metavar="N",
                        help="with --vectorization batched: --bag and --rerun record the first "
                             f"N episodes (default {RECORDED_EPISODES}), replayed one at a time "
                             "in single envs")
    marks = parser.add_argument_group("pass marks", "A missed mark prints one line naming the "
                                      "figure and the mark, and the exit status is 1")
    marks.add_argument("--fail-under", type=percent_arg, metavar="PCT",
                       help="fail when the success rate is under PCT percent")
    marks.add_argument("--max-final-distance", type=distance_arg, metavar="M",
                       help="fail when the mean final distance to the goal (m, ground truth) "
                            "is over M")
    parser.add_argument("--seed", type=non_negative_int_arg, default=0,
                        help="episode i uses seed SEED+i (an integer >= 0; default 0)")
    parser.add_argument("--stochastic", action="store_true",
                        help="sample actions instead of taking the mean action")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the metrics and "
                        "per-episode records as JSON")
    parser.add_argument("--video", type=Path, metavar="FILE.mp4|FILE.gif",
                        help="render the first --video-episodes episodes")
    parser.add_argument("--video-episodes", type=positive_int_arg, default=3)
    parser.add_argument("--plot", type=Path, metavar="FILE.png",
                        help="top-down trajectories of up to 16 episodes")
    parser.add_argument("--bag", type=Path, metavar="FILE.bag|FILE.mcap",
                        help="write the episodes as a ROS 1 bag or MCAP file (odom, tf, "
                             "joint_states, cmd_vel, goal, ground truth; simulated time; "
                             "needs the ros extra, not ROS)")
    parser.add_argument("--bag-format", choices=("ros1", "ros2"), default="ros1",
                        help="ros1: FILE.bag or FILE.mcap (ROS 1 messages); ros2: a rosbag2 "
                             "folder FILE (CDR messages, also /scan and /robot_description) "
                             "for ros2 bag and Foxglove, written from the evaluated episodes")
    parser.add_argument("--bag-storage", choices=("mcap", "sqlite3"), default="mcap",
                        help="storage of a ros2 bag (default: mcap)")
    parser.add_argument("--rerun", type=Path, metavar="FILE.rrd", help="write every evaluated "
                        "episode to a Rerun recording (needs the rerun extra)")
    parser.add_argument("--rerun-serve", action="store_true", help="stream the episodes to "
                        "Rerun's web viewer, served locally from the rerun-sdk package, and "
                        "keep serving until Ctrl-C or SIGTERM")
    parser.add_argument("--rerun-ports", nargs=2, type=positive_int_arg, default=(9876, 9090),
                        metavar=("GRPC", "WEB"), help="ports of --rerun-serve's gRPC server "
                        "and web viewer (default: Rerun's 9876 9090)")
    parser.add_argument("--rerun-bind", default="127.0.0.1", metavar="ADDRESS",
                        help="the IP address --rerun-serve's servers listen on (default "
                             "127.0.0.1: this machine only); an address of this machine's "
                             "network (0.0.0.0: every interface) shares the viewer and the "
                             "episodes with anyone who can reach it (docs/viewers.md)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_minari_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-eval``: returns the exit code (2 for bad arguments, models or env kwargs)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    require_train_extra("smartcar-eval", EVAL_MODULES)
    check_outputs(parser, args)
    check_minari_arguments(parser, args)
    _check_vectorization(parser, args)
    env_kwargs = dict(args.env_kwargs)
    if args.engine is not None:
        env_kwargs["engine"] = args.engine
    if args.random:
        env_id = args.env_id or DEFAULT_ENV_ID
        policy = Policy(RandomPolicy(args.seed), algo="random", env_id=env_id,
                        env_kwargs=env_kwargs,
                        normalizer_source="none (random actions)")
    else:
        try:
            policy = Policy.load(args.model or args.pretrained, algo=args.algo,
                                 env_id=args.env_id, env_kwargs=env_kwargs,
                                 normalizer=args.vecnormalize, device=args.device)
        except PolicyError as err:
            parser.error(str(err))
        if args.stochastic and is_onnx_path(policy.model_path):
            parser.error(f"--stochastic: {policy.model_path} holds the deterministic policy "
                         "only; sampled actions need the SB3 model (.zip)")
    model_path = policy.model_path or Path("random-policy")
    algo, env_id, env_kwargs = policy.algo, policy.env_id, policy.env_kwargs
    vecnormalize, source = policy.normalizer_path, policy.normalizer_source
    try:
        check_env(env_id, env_kwargs)  # here, not in a worker: a clear error
    except EnvSetupError as err:
        parser.error(str(err))
    warnings: list[str] = []
    hint = fail_under_hint(args.fail_under)
    if hint:
        warnings.append(hint)
        print(f"smartcar-eval: warning: {hint}", file=sys.stderr)
    if not args.random:
        print(f"smartcar-eval: normaliser: {source}", file=sys.stderr)
        if policy.warning:
            warnings.append(policy.warning)
            print(f"smartcar-eval: warning: {policy.warning}", file=sys.stderr)
    common = dict(env_id=env_id, seed=args.seed, env_kwargs=env_kwargs,
                  deterministic=not args.stochastic)
    steps = minari_steps(args)
    with contextlib.ExitStack() as stack:
        recorders = open_recorders(args, stack)
        try:
            records = _evaluate(args, policy, recorders, common, steps)
        except (ObservationShapeError, EnvSetupError) as err:
            parser.error(str(err))
        outputs: dict[str, Any] = {} if args.random else {"normaliser": vecnormalize or source}
        outputs.update(close_recorders(recorders))
        outputs.update(write_minari(parser, args, policy, records, steps, env_id, env_kwargs,
                                    reference_scores))
        summary = summarize(records)
        marks = check_marks(summary, args)
        if args.json is not None:
            payload = {
                "model": str(model_path if not args.pretrained else "pretrained:" + (
                    PRETRAINED_MODEL if args.pretrained == "default"
                    else f"{args.pretrained}/{PRETRAINED_MODEL}")),
                "algo": algo, "env": env_id, "env_kwargs": env_kwargs, "seed": args.seed,
                "n_envs": min(args.n_envs, args.episodes),  # the envs or cars made
                "deterministic": not args.stochastic,
                "vectorization": args.vectorization, "recorded_episodes": _recorded(args)
                if args.bag or args.rerun or args.rerun_serve else None,
                "marks": marks, "passed": all(mark["held"] for mark in marks),
                "normalizer": None if vecnormalize is None else str(vecnormalize),
                "normalizer_source": source, "warnings": warnings,
                **summary,
                "episode_records": [r.to_dict() for r in records],
            }
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(payload, indent=2) + "\n")
            outputs["json"] = args.json
        if args.plot is not None:
            from smartcar_gym.agents.plots import plot_trajectories

            tolerance = float(env_kwargs.get("goal_tolerance", 0.1))
            shown = " (first 16 shown)" if len(records) > 16 else ""
            plot_trajectories(records, args.plot, goal_tolerance_m=tolerance,
                              title=f"{model_path.name} on {env_id}: "
                                    f"{summary['success_rate']:.0%} success over "
                                    f"{count(len(records), 'episode')}{shown}")
            outputs["plot"] = args.plot
        if args.video is not None:
            n_frames = record_video(policy, args.video, n_episodes=args.video_episodes, **common)
            outputs[f"video ({n_frames} frames)"] = args.video
        if args.bag is not None and args.bag_format == "ros1":
            from smartcar_gym.agents.bag import write_bag

            n_messages = write_bag(policy, args.bag, n_episodes=_recorded(args), **common)
            outputs[f"bag ({n_messages} messages)"] = args.bag
        _print_summary(summary, model_path, env_id, args, outputs,
                       engine=env_kwargs.get("engine") or DEFAULT_ENGINE)
        for warning in warnings:  # again after the table, where the numbers are read
            print(f"smartcar-eval: warning: {warning}", file=sys.stderr)
        for mark in marks:
            print(f"smartcar-eval: {mark['line']}", file=sys.stderr)
        if args.rerun_serve:
            serve_until_interrupted(recorders)
    return 0 if all(mark["held"] for mark in marks) else 1


# -- batched evaluation and pass marks --------------------------------------------------------
#: episodes --bag and --rerun record in a batched evaluation without --record-episodes
RECORDED_EPISODES = 10


def _check_vectorization(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``--n-envs``'s default for the vectorization; ``--record-episodes`` only when batched."""
    batched = args.vectorization == "batched"
    if args.record_episodes is not None and not batched:
        parser.error("--record-episodes: only with --vectorization batched (otherwise --bag "
                     "and --rerun record every evaluated episode)")
    if args.n_envs is None:
        args.n_envs = DEFAULT_BATCH if batched else 1


def _recorded(args: argparse.Namespace) -> int:
    """How many episodes (the first ones) --bag and --rerun record."""
    if args.vectorization != "batched":
        return args.episodes
    return min(args.episodes, args.record_episodes or RECORDED_EPISODES)


def _evaluate(args: argparse.Namespace, policy: Policy, recorders: list[Any],
              common: dict[str, Any], steps: Any = None) -> list[Any]:
    """The episodes' records: single envs (in worker processes when --n-envs > 1), or one
    batch; the recorders of a batched evaluation get its first episodes replayed one at a
    time in single envs (the batch has no simulator to read per car). ``steps``: --minari's."""
    progress = not args.no_progress
    if args.vectorization != "batched":
        return evaluate_policy_episodes(policy, n_episodes=args.episodes, n_envs=args.n_envs,
                                        progress=progress, recorders=recorders, steps=steps,
                                        **common)
    records = evaluate_batched_episodes(policy, n_episodes=args.episodes, n_envs=args.n_envs,
                                        progress=progress, steps=steps, **common)
    if recorders:
        evaluate_policy_episodes(policy, n_episodes=_recorded(args), recorders=recorders,
                                 **common)
    return records


def check_marks(summary: dict[str, Any], args: argparse.Namespace) -> list[dict[str, Any]]:
    """The pass marks given (``--fail-under``, ``--max-final-distance``), each with its figure,
    whether it held and its line for the log."""
    marks: list[dict[str, Any]] = []
    if args.fail_under is not None:
        rate = 100.0 * summary["success_rate"]
        held = rate + 1e-9 >= args.fail_under
        marks.append({
            "option": "--fail-under", "figure": "success_rate_pct", "mark": args.fail_under,
            "value": rate, "held": held,
            "line": f"pass mark {'held' if held else 'missed'}: success rate "
                    f"{distinct_figure(rate, args.fail_under, 1)}% is "
                    f"{'not ' if held else ''}under --fail-under {args.fail_under:g}% "
                    f"({count(summary['episodes'], 'episode')})"})
    if args.max_final_distance is not None:
        mean = summary["mean_final_distance_m"]
        held = mean <= args.max_final_distance
        marks.append({
            "option": "--max-final-distance", "figure": "mean_final_distance_m",
            "mark": args.max_final_distance, "value": mean, "held": held,
            "line": f"pass mark {'held' if held else 'missed'}: mean final distance "
                    f"{distinct_figure(mean, args.max_final_distance, 3)} m is "
                    f"{'not ' if held else ''}over --max-final-distance "
                    f"{args.max_final_distance:g} m ({count(summary['episodes'], 'episode')})"})
    return marks


def fail_under_hint(fail_under: float | None) -> str | None:
    """A warning for a ``--fail-under`` that reads as a fraction (0.95 is 0.95 %, not 95 %)."""
    if fail_under is None or not 0.0 < fail_under <= 1.0:
        return None
    return (f"--fail-under {fail_under:g} is {fail_under:g} %, a percentage; for "
            f"{fail_under * 100:g} % pass --fail-under {fail_under * 100:g}")


def summary_title(name: str, env_id: str, engine: str, episodes: int, seed: int,
                  actions: str) -> str:
    """The summary table's header: ``policy.zip on SmartCar-v0 (mujoco): 100 episodes, seeds
    0..99, deterministic``; ``actions`` says how they were chosen (deterministic, stochastic,
    random)."""
    seeds = f"seed {seed}" if episodes == 1 else f"seeds {seed}..{seed + episodes - 1}"
    return f"{name} on {env_id} ({engine}): {count(episodes, 'episode')}, {seeds}, {actions}"


def _print_summary(summary: dict[str, Any], model_path: Path, env_id: str,
                   args: argparse.Namespace, files: dict[str, Any],
                   engine: str = DEFAULT_ENGINE) -> None:
    from rich.console import Console
    from rich.table import Table

    def fmt(value: float | None, spec: str) -> str:
        return "n/a" if value is None else format(value, spec)

    actions = ("random actions" if args.random
               else "stochastic" if args.stochastic else "deterministic")
    table = Table(title=summary_title(model_path.name, env_id, engine, summary["episodes"],
                                      args.seed, actions))
    table.add_column("metric")
    table.add_column("value", justify="right", overflow="fold")  # paths in full
    table.add_row("success rate", fmt(summary["success_rate"], ".1%"))
    table.add_row("mean return", f"{summary['mean_return']:.2f} ± {summary['std_return']:.2f}")
    table.add_row("mean time to goal (s, successes)", fmt(summary["mean_time_to_goal_s"], ".2f"))
    table.add_row("mean final distance (m)", fmt(summary["mean_final_distance_m"], ".3f"))
    table.add_row("mean final odometry error (m)",
                  fmt(summary["mean_final_odom_error_m"], ".3f"))
    for name, path in files.items():
        table.add_row(name, str(path))
    Console().print(table)


def run() -> NoReturn:
    """The ``smartcar-eval`` command's process: ``main`` through ``process_start.run_command``
    (the process set up, then ended without Python's teardown)."""
    run_command(main)


if __name__ == "__main__":
    run()
