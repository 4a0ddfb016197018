"""``smartcar-bench``: a policy or the DWA baseline on the BARN test worlds, the challenge's table.

::

    smartcar-bench barn --driver dwa --engine pybullet --runs 1 --json dwa.json --plot dwa.png
        (DWA as the challenge's move_base: no map, its costmaps from the laser;
        --env-kwargs map_mode=known for the old protocol on the known map)
    smartcar-bench barn --model runs/ppo_SmartCarBARN-v0_s0 --runs 10 --fail-under 80

Every test world of the world file (the shipped one's: 0, 6, ..., 294; ``--worlds`` for
others) K times (run k seeded ``--seed + k``: the engines are deterministic, so the K runs
repeat one another unless ``--env-kwargs`` adds noise, such as
``laser='{noise_std_m: 0.01}'``); the table says the rates of success, collision and
timeout, the mean time of the successful runs and the mean score on both scales
(docs/barn.md). ``--fail-under`` and ``--max-final-distance`` are smartcar-eval's pass marks
(exit status 1 when one is missed).
The ``--n-envs`` cars are the id's vector env: one batched env where the engine batches
(planar, MuJoCo: ``SmartCarBatchVectorEnv``), elsewhere a loop of single envs; the runs go
through the episode runner (``bench.runs``). ``--workers W`` shares the runs among W
processes (``bench.workers``), each with its own driver and ``--n-envs`` cars, a car that
frees taking the next run no worker has taken (``runner.JobQueue``; the same records: a run
depends on its world and seed alone), and its share of the cores for the compiled loops
(``num_threads`` of the CPUs / W); pybullet steps one car at a time in a process, so there
it takes every core, and the planar batch's Python between its compiled loops runs on W
cores instead of one.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smartcar_gym.agents.atomic_files import output_path_error
from smartcar_gym.agents.cli_args import (
    distance_arg,
    key_value_arg,
    non_negative_int_arg,
    percent_arg,
    positive_int_arg,
    rate_arg,
)
from smartcar_gym.agents.cli_eval import check_marks
from smartcar_gym.agents.env_factory import EnvSetupError, check_env
from smartcar_gym.agents.vec_envs import make_batched_env
from smartcar_gym.bench import workers
from smartcar_gym.bench.drivers import DRIVERS, DriverError, PolicyDriver, make_driver
from smartcar_gym.bench.report import plot_runs, summarize, table
from smartcar_gym.bench.runs import BarnJob, BarnRunError, RunRecord, barn_jobs, run_barn
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv
from smartcar_gym.envs.vector.view import CarView
from smartcar_gym.parallel import run_chunks
from smartcar_gym.sim.engines import DEFAULT_ENGINE, add_engine_argument, on_engine
from smartcar_gym.worlds.barn import BarnWorldError, load_worlds

ENV_ID = "SmartCarBARN-v0"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="smartcar-bench", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")
    barn = sub.add_parser("barn", help="the BARN challenge's 50 test worlds",
                          description="Runs a policy or a classical driver on the BARN test "
                                      "worlds and prints the challenge's table.")
    source = barn.add_mutually_exclusive_group()
    source.add_argument("--model", type=Path, help="a model .zip or a run folder")
    source.add_argument("--pretrained", metavar="NAME", help="a shipped policy by name")
    source.add_argument("--driver", metavar="NAME",
                        help=f"a classical driver: {', '.join(sorted(DRIVERS))} (the default: "
                             "dwa), run on the challenge's protocol: no map (map_mode=laser; "
                             "map_mode=known, or localize=true without map_mode: the known map)")
    add_engine_argument(barn)
    barn.add_argument("--goal-rate", type=rate_arg, metavar="HZ",
                      help="a classical driver's goal sent again at this rate, as the "
                           "challenge's launch sends it (rostopic pub -r 10: --goal-rate 10; "
                           "move_base then runs no recovery behaviour); default: sent once")
    barn.add_argument("--runs", type=positive_int_arg, default=1, metavar="K",
                      help="runs of each world (default 1; the challenge: 10)")
    barn.add_argument("--worlds", type=non_negative_int_arg, nargs="+", metavar="I",
                      help="these worlds (each once) instead of the world file's test worlds "
                           "(the shipped file's: the challenge's 50)")
    barn.add_argument("--world-file", type=Path, metavar="FILE.npz",
                      help="the worlds (default: the shipped barn_worlds.npz)")
    barn.add_argument("--n-envs", type=positive_int_arg, default=1,
                      help="cars stepped side by side (one driver call for all; one "
                           "batched env where the engine batches; at most one per run)")
    barn.add_argument("--workers", type=positive_int_arg, default=1, metavar="W",
                      help="processes sharing the runs, each on --n-envs cars of its own "
                           "(a car that frees takes the next run none has taken) and the "
                           "CPUs / W threads (the same records; pybullet, which steps one car "
                           "at a time in a process: one a core; default 1)")
    barn.add_argument("--seed", type=non_negative_int_arg, default=0,
                      help="run k of a world is reset with seed + k (default 0)")
    barn.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                      type=key_value_arg,
                      help="SmartCarBARN-v0 keyword arguments (YAML values) over a policy's "
                           "own, e.g. laser='{noise_std_m: 0.01}' (the noise of run k drawn "
                           "with seed + k: the K runs differ) or randomize=odometry")
    barn.add_argument("--device", default="cpu", help="torch device of --model")
    barn.add_argument("--json", type=Path, metavar="FILE", help="write the table and every run")
    barn.add_argument("--plot", type=Path, metavar="FILE.png",
                      help="draw the first runs of the --plot-worlds")
    barn.add_argument("--plot-worlds", type=non_negative_int_arg, nargs="+", metavar="I",
                      help="the worlds --plot draws (default: the first four run)")
    marks = barn.add_argument_group("pass marks", "as smartcar-eval's: exit status 1 when one "
                                                  "is missed")
    marks.add_argument("--fail-under", type=percent_arg, metavar="PCT",
                       help="least success rate, percent")
    marks.add_argument("--max-final-distance", type=distance_arg, metavar="M",
                       help="largest mean final distance to the goal, m")
    barn.add_argument("--quiet", action="store_true", help="no line per run")
    barn.set_defaults(command_parser=barn)  # its errors read "smartcar-bench barn: error: ..."
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-bench``: the exit code (2 for bad arguments or a world that cannot be run, 1
    for a missed pass mark)."""
    args = build_parser().parse_args(argv)
    parser = args.command_parser
    for option in ("json", "plot"):
        path = getattr(args, option)
        why = None if path is None else output_path_error(path)
        if why is not None:
            parser.error(f"--{option}: {why}")
    if args.plot is not None and (why := _plot_error(args.plot)) is not None:
        parser.error(f"--plot {args.plot}: {why}")
    try:
        worlds = load_worlds(args.world_file)
        chosen = worlds.test_worlds if args.worlds is None else tuple(args.worlds)
        for index in chosen:
            worlds.world(index)
        _check_worlds_chosen(args, chosen)
        driver, name, trained_with = driver_for(args)
        kwargs = _env_kwargs(args, trained_with)
        check_env(ENV_ID, kwargs)  # a bad --env-kwargs: one line naming it
        jobs = barn_jobs(chosen, args.runs, args.seed)
    except (BarnWorldError, DriverError, EnvSetupError) as err:
        parser.error(str(err))
    plotted = set() if args.plot is None else set(args.plot_worlds or chosen[:4])
    try:
        if args.workers > 1 and len(jobs) > 1:
            ran = workers.run(args, kwargs, chosen, jobs, plotted)
        else:
            ran = run_here(driver, args.n_envs, kwargs, chosen, jobs, plotted, args.quiet)
    except (BarnWorldError, DriverError, EnvSetupError) as err:
        parser.error(str(err))
    records, failed, batched = ran.records, ran.failed, ran.batched
    summary = summarize(records)
    marks = check_marks(summary, args)
    engine = args.engine or DEFAULT_ENGINE
    print(f"smartcar-bench barn: {name} on {engine}, {len(chosen)} worlds x {args.runs} "
          f"run(s), seed {args.seed}")
    print(table(summary, name))
    if args.json is not None:
        payload = {"benchmark": "barn", "driver": name, "goal_rate_hz": args.goal_rate,
                   "env": ENV_ID, "engine": engine,
                   "vectorization": "batched" if batched else "single",
                   "runs_per_world": args.runs, "seed": args.seed,
                   "env_kwargs": {k: v for k, v in kwargs.items() if k != "world_file"},
                   "worlds": list(chosen),
                   "scale": ran.scale, "marks": marks,
                   "passed": failed is None and all(m["held"] for m in marks), **summary,
                   **({} if failed is None else {"error": failed}),
                   "records": [r.to_dict() for r in records]}
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(payload, indent=2) + "\n")
        print(f"wrote {args.json}")
    if failed is not None:
        parser.error(f"{failed} (the {len(records)} run(s) before it are kept"
                     f"{'' if args.json is None else f' in {args.json}'})")
    if args.plot is not None:
        dashed = ("the known map's path, not given to the car" if kwargs.get("map_mode") ==
                  "laser" else "the global path")
        plot_runs(records, worlds, ran.scale, args.plot,
                  f"{name} on {engine}: {summary['success_rate']:.0%} success (dashed: "
                  f"{dashed})", ran.paths)
        print(f"wrote {args.plot}")
    for mark in marks:
        print(f"smartcar-bench: {mark['line']}", file=sys.stderr)
    return 0 if all(m["held"] for m in marks) else 1


@dataclass
class Ran:
    """What the runs gave: every record in the order of the jobs (where a run failed, those
    that had ended), the failure's line (None: none), the global paths planned (by world),
    the protocol's scale and whether the cars were one batched env."""

    records: list[RunRecord]
    failed: str | None
    paths: dict[int, Any]
    scale: float
    batched: bool


def run_here(driver: Any, n_envs: int, kwargs: dict[str, Any], chosen: Sequence[int],
             jobs: Sequence[BarnJob], plotted: set[int], quiet: bool,
             cars_for: int | None = None, shared: Any | None = None) -> Ran:
    """``jobs`` run by ``driver`` on ``n_envs`` cars (at most one a job, or one for each of
    ``cars_for`` jobs): DriverError for a policy of another observation space,
    BarnWorldError for a world without a way. ``shared``: in a worker (``workers.run``), the
    index the workers take the jobs by (``runner.JobQueue``); its records are of the jobs it
    took."""
    envs = make_batched_env(ENV_ID, min(n_envs, cars_for or len(jobs)), kwargs)  # no idle cars
    try:
        cars = CarView(envs)
        if isinstance(driver, PolicyDriver):
            driver.check(ENV_ID, envs.single_observation_space)
        _plan_worlds(cars, chosen, getattr(envs.unwrapped, "threads", 1))
        failed = None
        try:
            records = run_barn(envs, driver, jobs,
                               keep=lambda job: job.world in plotted and job.run == 0,
                               report=None if quiet else _report,
                               shared=shared)
        except BarnRunError as err:  # the runs so far are kept
            records, failed = err.records, str(err)
        paths = {}  # the global paths every car's task planned, by world
        for task in cars.tasks():
            paths.update(task.planned_paths)
        return Ran(records, failed, paths, cars.task.protocol.scale,
                   isinstance(envs.unwrapped, SmartCarBatchVectorEnv))
    finally:
        envs.close()


def _plot_error(path: Path) -> str | None:
    """Why ``--plot`` cannot be written (an extension matplotlib does not write, or no
    matplotlib), else None: said before the runs, not after them."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
    except ImportError:
        return "drawing needs matplotlib (pip install matplotlib)"
    kinds = FigureCanvasAgg.get_supported_filetypes()
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in kinds:
        return (f"matplotlib writes {', '.join('.' + k for k in sorted(kinds))}, not "
                f"{'no extension' if not suffix else '.' + suffix}")
    return None


def _check_worlds_chosen(args: argparse.Namespace, chosen: Sequence[int]) -> None:
    """EnvSetupError (one line) for a world given twice in ``--worlds`` (its runs would repeat
    one another: ``--runs`` runs a world K times) or a ``--plot-worlds`` world not run."""
    repeated = sorted({i for i in chosen if list(chosen).count(i) > 1})
    if repeated:
        raise EnvSetupError(f"--worlds: world(s) {', '.join(map(str, repeated))} given more "
                            "than once; each world is run --runs times")
    if args.plot_worlds:
        if args.plot is None:
            raise EnvSetupError("--plot-worlds: needs --plot FILE.png")
        missing = [i for i in args.plot_worlds if i not in chosen]
        if missing:
            raise EnvSetupError(f"--plot-worlds: world(s) {', '.join(map(str, missing))} are "
                                "not run; draw worlds among --worlds (the default: the file's "
                                "test worlds)")


def _plan_worlds(cars: CarView, chosen: Sequence[int], threads: int = 1) -> None:
    """Every chosen world's global path, planned before the first run (BarnWorldError, one
    line, for the first chosen world without a way for this car); every task of the cars
    shares them. The worlds are planned over the batch's ``threads`` (scipy's KD-tree and
    Dijkstra free the GIL): each world's path is its own, whichever thread plans it."""
    tasks, worlds = cars.tasks(), list(chosen)

    def plan(start: int, stop: int) -> None:
        for k in range(start, stop):
            tasks[0].plan(worlds[k])

    run_chunks(plan, len(worlds), threads, min_chunk=1)
    for task in tasks[1:]:
        task.planned_paths.update(tasks[0].planned_paths)


def driver_for(args: argparse.Namespace, threads: int | None = None
               ) -> tuple[Any, str, dict[str, Any]]:
    """The driver the arguments name, its name in the table, and the env kwargs it runs with
    unless ``--env-kwargs`` says otherwise: a policy's, those it was trained with (a policy
    of SmartCarBARN-v0); a classical driver's, the challenge's protocol (``map_mode`` laser:
    no map), or the known map when ``localize`` is given without ``map_mode`` (it matches
    scans to that map).
    ``threads``: a classical driver's for its compiled loops (None: its default, one per
    CPU)."""
    if args.model is None and args.pretrained is None:
        name, given = args.driver or "dwa", dict(args.env_kwargs)
        # localize=true alone: the known map (its scans matched to the cylinders); with
        # map_mode=laser, the laser map and the scans matched to the car's own map
        known = "localize" in given and given.get("map_mode") != "laser"
        if args.goal_rate is not None and (
                known or given.get("map_mode", DRIVER_MAP_MODE) != "laser"):
            raise DriverError("--goal-rate: the goal is sent to move_base, which runs with "
                              "map_mode=laser only (on the known map the driver has no "
                              "move_base cycle)")
        if "planner_frequency" in given:
            raise DriverError("--env-kwargs planner_frequency: a classical driver is move_base, "
                              "whose planner runs at the challenge's rate (its PLANNING state "
                              "waits for the next plan); it is a policy's map's setting")
        options: dict[str, Any] = {} if threads is None else {"threads": threads}
        if args.goal_rate is not None:
            options["goal_rate_hz"] = args.goal_rate
        return (make_driver(name, **options), name,
                {} if known else {"map_mode": DRIVER_MAP_MODE})
    if args.goal_rate is not None:
        raise DriverError("--goal-rate: a classical driver's (move_base's goal); a policy "
                          "takes its goal once")
    from smartcar_gym.agents.models import PRETRAINED_POLICIES
    from smartcar_gym.agents.policies import Policy, PolicyError

    if args.pretrained is not None and args.pretrained not in PRETRAINED_POLICIES:
        raise DriverError(f"--pretrained: no shipped policy {args.pretrained!r}; the shipped "
                          f"ones are {', '.join(PRETRAINED_POLICIES)}")
    source = args.model if args.model is not None else args.pretrained
    # a map mode the policy was not trained in is refused by the policy's own check
    mode = {k: v for k, v in dict(args.env_kwargs).items() if k == "map_mode"}
    try:
        policy = Policy.load(source, device=args.device, env_kwargs=mode or None)
    except PolicyError as err:
        raise DriverError(str(err)) from None
    name = f"pretrained:{args.pretrained}" if args.model is None else str(args.model)
    trained_with = dict(policy.env_kwargs) if policy.env_id == ENV_ID else {}
    return PolicyDriver(policy, name), name, trained_with


#: a classical driver's map mode unless told: the challenge's (move_base builds its costmaps
#: from the laser; ``--env-kwargs map_mode=known`` runs the old protocol on the known map)
DRIVER_MAP_MODE = "laser"
#: a policy's env kwargs the benchmark does not take: the protocol sets the episode's length and
#: runs the nominal car (a policy that learnt with ``randomize`` is measured without it)
NOT_FROM_POLICY = ("max_episode_steps", "world_file", "render_mode", "randomize")


def _env_kwargs(args: argparse.Namespace, trained_with: dict[str, Any]) -> dict[str, Any]:
    """The env's kwargs: what a policy was trained with (its laser, lookahead, model), moved
    to ``--engine`` (``on_engine``: another engine's own kwargs left out), ``--env-kwargs``
    over them, and the world file."""
    kept = {k: v for k, v in trained_with.items() if k not in NOT_FROM_POLICY}
    given = dict(args.env_kwargs)
    for key, option in (("engine", "--engine"), ("world_file", "--world-file")):
        if key in given:
            raise EnvSetupError(f"--env-kwargs: {key} is set by {option}, not here")
    if "max_episode_steps" in given:
        raise EnvSetupError("--env-kwargs: max_episode_steps is set by the protocol (each run "
                            "ends at its timeout, which follows the car), not here")
    return {**on_engine(kept, args.engine or DEFAULT_ENGINE), **given,
            "world_file": args.world_file}


def _report(record: RunRecord) -> None:
    print(f"world {record.world:3d} run {record.run}: {record.outcome} after {record.steps} "
          f"steps, time {record.time_s:.1f} s, score {record.score:.3f}", file=sys.stderr,
          flush=True)


if __name__ == "__main__":
    sys.exit(main())
