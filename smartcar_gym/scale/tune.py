"""``smartcar-tune``: a Ray Tune sweep whose trials are ``smartcar-train`` runs.

::

    smartcar-tune --out sweeps/lr                        # the shipped space, local Ray
    smartcar-tune --space my_space.yaml --seeds 0 1 2 --num-samples 4 --out sweeps/s1
    smartcar-tune --hyperparams "learning_rate={grid: [1e-4, 3e-4]}" --out sweeps/s2
    smartcar-tune --address auto --space my_space.yaml --out /shared/sweeps/s3  # a cluster
    smartcar-tune --engine planar --vectorization batched --out sweeps/planar  # the fast preset
    smartcar-tune --resume sweeps/s1                      # after a crash or Ctrl-C

Without ``--address``, ``RAY_ADDRESS`` names the cluster; with neither, a new local Ray
instance runs the sweep.

``<out>`` holds ``sweep.yaml`` (the checked space), ``tune/`` (Ray Tune's experiment state,
for ``--resume``), one run folder per trial (``trial_00000/``, ...), ``results.csv``,
``results.json`` and ``best_hyperparams.yaml``. See ``space`` for the space file.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents.atomic_files import output_path_error
from smartcar_gym.agents.cli_args import key_value_arg, positive_int_arg
from smartcar_gym.agents.vec_envs import VECTORIZATIONS
from smartcar_gym.scale import results as results_mod
from smartcar_gym.scale.ray_session import (
    RayUnavailableError,
    ResourceError,
    check_cpus,
    ray_session,
    require_ray,
)
from smartcar_gym.scale.space import (
    SpaceError,
    Sweep,
    apply_overrides,
    build_sweep,
    env_kwargs_samples,
    load_space,
    shipped_space_file,
)
from smartcar_gym.scale.trial import TRIAL_KEY
from smartcar_gym.sim.engines import add_engine_argument

PROG = "smartcar-tune"
EXPERIMENT = "tune"  # Ray Tune's folder in <out>
INTERRUPTED_EXIT_CODE = 130
# What --resume reads from <out>; the options that would change it.
SWEEP_OPTIONS = ("space", "hyperparams", "seeds", "num_samples", "timesteps", "cpus_per_trial",
                 "no_early_stopping", "engine", "vectorization")
ADDRESS_ENV = "RAY_ADDRESS"  # the cluster when --address is not given (Ray's own variable)


def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-tune`` argument parser."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="Sweep smartcar-train runs over a search space with Ray Tune "
        "(grid and random search, ASHA early stopping on evaluation success). Needs the ray "
        "extra: pip install \"smartcar-gym[ray]\".")
    parser.add_argument("--space", type=Path, default=None, metavar="SPACE.yaml",
                        help="search space (default: the shipped smartcar_gym/config/"
                             "tune_ppo.yaml, with --vectorization batched tune_ppo_batched.yaml)")
    parser.add_argument("--hyperparams", nargs="+", type=key_value_arg, default=None,
                        metavar="KEY=VALUE", help="set or search hyperparameters: a YAML "
                        "value (3e-4) or a dimension (\"{grid: [1e-4, 3e-4]}\", \"{loguniform:"
                        " [1e-4, 1e-3]}\", choice, uniform, randint)")
    parser.add_argument("--seeds", nargs="+", type=int, default=None, metavar="SEED",
                        help="a grid over these seeds (every configuration with each seed)")
    parser.add_argument("--num-samples", type=positive_int_arg, default=None,
                        help="times the grid is run, with new draws of the random dimensions "
                             "(default: the space's num_samples, else 1)")
    parser.add_argument("--timesteps", type=positive_int_arg, default=None,
                        help="environment steps per trial (default: the space's timesteps)")
    parser.add_argument("--cpus-per-trial", type=positive_int_arg, default=None,
                        help="CPUs Ray reserves per trial (default: the space's, else what a "
                             "trial uses: 1, 2 for a batched trial with eval_async; a subproc "
                             "trial runs n_envs env processes, a batched one steps its cars on "
                             "this many threads)")
    add_engine_argument(parser, what="every trial's")
    parser.add_argument("--vectorization", choices=VECTORIZATIONS, default=None,
                        help="how each trial runs its envs, as smartcar-train's option "
                             "(default: the space's, else subproc); batched: the fast preset, "
                             "the hyperparameters' <env>-batched-<engine> entry (e.g. 32 planar "
                             "cars in one process with --engine planar), on an engine with a "
                             "car batch")
    parser.add_argument("--no-early-stopping", action="store_true",
                        help="run every trial to the end (no ASHA)")
    parser.add_argument("--num-cpus", type=positive_int_arg, default=None,
                        help="CPUs of the local Ray instance (default: all)")
    parser.add_argument("--address", default=None,
                        help="a running Ray cluster (\"auto\", HOST:6379 or ray://HOST:10001) "
                             f"instead of a local instance (default: ${ADDRESS_ENV} if set); "
                             "--out must then be a folder every node sees at the same path")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--out", type=folder_arg, default=None, metavar="DIR",
                       help="new sweep folder: run folders, results, Tune state")
    where.add_argument("--resume", type=folder_arg, default=None, metavar="DIR",
                       help="continue the sweep in DIR (unfinished and failed trials continue "
                            "from their latest checkpoint)")
    return parser


def folder_arg(text: str) -> Path:
    """argparse type of --out and --resume: a folder, not a URI (checked on the raw text:
    ``Path`` turns ``s3://b`` into ``s3:/b``)."""
    if "://" in text:
        raise argparse.ArgumentTypeError(
            f"{text}: the run folders are files; give a local folder or one on a shared file "
            "system (NFS), not a URI")
    return Path(text)


class SweepSetupError(ValueError):
    """The sweep cannot start (the message says why)."""


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-tune``: 0 when every trial completed or was stopped early, 1 if a trial
    failed, 130 if interrupted (``--resume`` continues), 2 for bad input or no Ray."""
    parser = build_parser()
    args = parser.parse_args(argv)
    given = "--address" if args.address is not None else ADDRESS_ENV
    address = args.address if args.address is not None else os.environ.get(ADDRESS_ENV) or None
    if address is not None and args.num_cpus is not None:
        parser.error(f"--num-cpus sets the CPUs of a new local Ray instance; a running cluster "
                     f"({given}) has its own: give one or the other")
    try:
        require_ray("ray.tune")
        sweep, out = (resumed_sweep(args) if args.resume is not None else new_sweep(args))
        with ray_session(address, args.num_cpus):
            check_cpus([sweep.cpus_per_trial], "a trial", "cpus_per_trial (--cpus-per-trial)")
            rows = run_sweep(sweep, out, resume=args.resume is not None)
    except (SpaceError, SweepSetupError, RayUnavailableError, ResourceError) as err:
        where = (f" ({ADDRESS_ENV}; unset it for a new local instance)"
                 if isinstance(err, RayUnavailableError) and address and given == ADDRESS_ENV
                 else "")
        print(f"{PROG}: error: {err}{where}", file=sys.stderr)
        return 2
    names = list(sweep.dimensions())
    written = results_mod.write_results(rows, names, out, sweep.algo, sweep.env,
                                        sweep.vectorization)
    results_mod.print_table(rows, names, f"{PROG}: {len(rows)} trials in {out}")
    print("written: " + ", ".join(str(p) for p in written))
    if any(row.status == results_mod.UNFINISHED for row in rows):
        print(f"{PROG}: the sweep stopped before every trial ended; continue it with: "
              f"{PROG} --resume {out}", file=sys.stderr)
        return INTERRUPTED_EXIT_CODE
    return 1 if any(row.status == results_mod.ERROR for row in rows) else 0


def new_sweep(args: argparse.Namespace) -> tuple[Sweep, Path]:
    """The checked sweep and its folder from the command line (nothing is written yet)."""
    out = _folder(args.out)
    problem = output_path_error(out / "sweep.yaml")
    if problem:
        raise SweepSetupError(f"--out: {problem}")
    if (out / "sweep.yaml").exists():
        raise SweepSetupError(f"{out} already holds a sweep; continue it with {PROG} --resume "
                              f"{out}, or choose another --out")
    data, path = load_space(args.space if args.space is not None else shipped_space_file(
        vectorization=args.vectorization or "subproc"))
    data = apply_overrides(data, args.hyperparams, args.seeds, num_samples=args.num_samples,
                           timesteps=args.timesteps, cpus_per_trial=args.cpus_per_trial,
                           vectorization=args.vectorization)
    if args.no_early_stopping:
        data["early_stopping"] = None
    if args.engine is not None:
        data["env_kwargs"] = {**(data.get("env_kwargs") or {}), "engine": args.engine}
    sweep = build_sweep(data, path, base_dir=path.parent,
                        fit_early_stopping=args.timesteps is not None)
    _check_env_kwargs(sweep, "--vectorization batched" if args.vectorization is not None
                      else f"{sweep.source}: vectorization: batched")
    for note in sweep.notes:
        print(f"{PROG}: note: {note}", file=sys.stderr)
    n_envs = sweep.hyperparams.get("n_envs")
    if sweep.vectorization == "subproc" and isinstance(n_envs, int) \
            and n_envs > sweep.cpus_per_trial:
        print(f"{PROG}: note: each trial runs n_envs={n_envs} env processes on "
              f"cpus_per_trial={sweep.cpus_per_trial} reserved CPU(s)", file=sys.stderr)
    return sweep, out


def resumed_sweep(args: argparse.Namespace) -> tuple[Sweep, Path]:
    """The sweep saved in ``--resume DIR``."""
    given = [f"--{name.replace('_', '-')}" for name in SWEEP_OPTIONS
             if getattr(args, name) not in (None, False)]
    if given:
        raise SweepSetupError(f"--resume continues the sweep as it was started; "
                              f"{', '.join(given)} cannot be changed")
    out = _folder(args.resume)
    if not (out / "sweep.yaml").is_file():
        raise SweepSetupError(f"--resume: {out / 'sweep.yaml'} not found (is {out} a "
                              f"{PROG} --out folder?)")
    data, path = load_space(out / "sweep.yaml")
    from ray import tune

    if not tune.Tuner.can_restore(str(out / EXPERIMENT)):
        raise SweepSetupError(f"--resume: {out / EXPERIMENT} holds no Ray Tune state (the "
                              "sweep stopped within its first seconds); start it again in "
                              "another --out folder")
    return build_sweep(data, path), out


def run_sweep(sweep: Sweep, out: Path, resume: bool) -> list[results_mod.TrialRow]:
    """Run (or continue) the sweep on the connected Ray cluster; the trials' rows."""
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler, FIFOScheduler

    from smartcar_gym.scale.trial import run_trial

    trainable = tune.with_resources(tune.with_parameters(run_trial, out=str(out), sweep=sweep),
                                    {"cpu": sweep.cpus_per_trial})
    path = str(out / EXPERIMENT)
    if resume:
        tuner = tune.Tuner.restore(path, trainable, resume_unfinished=True,
                                   resume_errored=True)
    else:  # Ray is up and the trials fit: now the folder becomes a sweep
        from smartcar_gym.agents.callbacks import atomic_write_text

        atomic_write_text(out / "sweep.yaml", "# smartcar-tune sweep (checked search space)\n"
                          + yaml.safe_dump(sweep.to_yaml(), sort_keys=False))
        asha = sweep.early_stopping
        scheduler = FIFOScheduler() if asha is None else ASHAScheduler(
            time_attr="timesteps", max_t=sweep.timesteps, grace_period=asha["grace_period"],
            reduction_factor=asha["reduction_factor"])
        # The trials are listed here (Sweep.trial_values: the seeds of a configuration share
        # its random draws), and Tune runs them as a grid over their searched values.
        tuner = tune.Tuner(
            trainable, param_space={TRIAL_KEY: tune.grid_search(sweep.trial_values())},
            tune_config=tune.TuneConfig(
                metric="success_rate", mode="max", scheduler=scheduler,
                trial_dirname_creator=_trial_dirname),
            run_config=tune.RunConfig(storage_path=str(out), name=EXPERIMENT, verbose=1),
        )
    grid = tuner.fit()
    return trial_rows(grid, sweep, out)


def trial_rows(grid: Any, sweep: Sweep, out: Path) -> list[results_mod.TrialRow]:
    """A row per trial of the sweep, in trial order, from Tune's ``ResultGrid`` (metrics,
    errors) and its experiment's trials (status, config: also of trials that never ran)."""
    import logging

    from ray import tune

    from smartcar_gym.scale.trial import plain

    # Tune warns about each trial without results (not started before an interrupt)
    quiet = logging.getLogger("ray.tune.analysis.experiment_analysis")
    level, quiet.level = quiet.level, logging.ERROR
    try:
        trials = {Path(t.path).name: t for t in
                  tune.ExperimentAnalysis(grid.experiment_path).trials}
        results = {Path(r.path).name: r for r in grid}
    finally:
        quiet.setLevel(level)
    rows = []
    for name, trial in sorted(trials.items()):
        result = results.get(name)
        metrics = (result.metrics if result is not None else None) or {}
        values = plain((trial.config or {}).get(TRIAL_KEY, {}))
        config = sweep.trial_config(values)
        timesteps = metrics.get("timesteps")
        error = None if result is None or result.error is None else _first_line(result.error)
        rows.append(results_mod.TrialRow(
            trial=name, values={n: values.get(n) for n in sweep.dimensions()},
            status=results_mod.trial_status(trial.status, timesteps, sweep.timesteps,
                                            error is not None),
            success_rate=metrics.get("success_rate"), mean_reward=metrics.get("mean_reward"),
            timesteps=timesteps, wall_time_s=metrics.get("wall_time_s"),
            node_id=metrics.get("node_id"), error=error, run_dir=str(out / name),
            hyperparams={**config["hyperparams"], "n_timesteps": sweep.timesteps},
            env_kwargs=config["env_kwargs"], seed=config["seed"]))
    return rows


def _trial_dirname(trial: Any) -> str:
    from smartcar_gym.scale.trial import trial_folder

    return trial_folder(trial.trial_id)


def _folder(path: Path) -> Path:
    if path.exists() and not path.is_dir():
        raise SweepSetupError(f"{path} is not a folder")
    return path.absolute()


def _check_env_kwargs(sweep: Sweep, batched_by: str) -> None:
    """Make the env once with each env_kwargs value a trial can get (a bad one fails here);
    a batched sweep's cars must be a batch (``batched_by`` names where it was asked for)."""
    from smartcar_gym.agents.env_factory import EnvSetupError, check_env, given_kwargs
    from smartcar_gym.envs.vector.make import loop_reason
    from smartcar_gym.sim.engines import batch_engines

    for kwargs in env_kwargs_samples(sweep):
        try:
            check_env(sweep.env, kwargs)
        except EnvSetupError as err:
            raise SweepSetupError(f"{sweep.source}: env_kwargs: {err}") from err
        why = loop_reason(sweep.env, kwargs) if sweep.vectorization == "batched" else None
        if why is not None:
            raise SweepSetupError(
                f"{batched_by}: {sweep.env} with {given_kwargs(kwargs)} runs as a loop of "
                f"single envs in one process, not a batch ({why}); give an engine with a car "
                f"batch ({', '.join(batch_engines())}), or --vectorization subproc")


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    lines = [line for line in text.splitlines() if line.strip()]
    return lines[-1].strip() if lines else type(error).__name__


if __name__ == "__main__":
    sys.exit(main())
