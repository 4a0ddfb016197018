"""``smartcar-bench barn --workers W``: the runs shared among W processes (``run``), each with
its own driver and cars and its share of the cores; a car that frees takes the next run no
worker has taken (``runner.JobQueue`` over one index, ``SHARED``). A run depends on its
world and seed alone, so the records are one process's, to the bit."""

from __future__ import annotations

import argparse
import multiprocessing
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from smartcar_gym.bench.runs import BarnJob

#: in a worker process of ``run``: the index of the next job no worker has taken (a
#: ``multiprocessing.Value``, inherited when the worker starts); None in one process
SHARED: Any = None


def _share(shared: Any) -> None:
    """A worker's initializer: the jobs' shared index (``SHARED``)."""
    global SHARED
    SHARED = shared


def run(args: argparse.Namespace, kwargs: dict[str, Any], chosen: Sequence[int],
        jobs: Sequence[BarnJob], plotted: set[int]) -> Any:
    """The command's runs (``cli.run_here``) in ``--workers`` processes, each on cars of its
    own, taking the next job of all as a car frees: one ``cli.Ran``, the records in the order
    of the jobs."""
    from smartcar_gym.bench.cli import Ran  # the command's (it imports this module)

    count = min(args.workers, len(jobs))
    options = {k: v for k, v in vars(args).items() if k != "command_parser"}
    context = multiprocessing.get_context("spawn")  # no copy of this process's threads
    shared = context.Value("q", 0)
    with ProcessPoolExecutor(count, mp_context=context, initializer=_share,
                             initargs=(shared,)) as pool:
        # each worker's cars: as many as a fixed share of the jobs would need
        parts = list(pool.map(_shard, [options] * count, [kwargs] * count, [chosen] * count,
                              [jobs] * count, [plotted] * count,
                              [-(-len(jobs) // count)] * count))
    order = {job: k for k, job in enumerate(jobs)}
    records = sorted((r for part in parts for r in part.records),
                     key=lambda r: order[BarnJob(r.world, r.run, r.seed)])
    failed = next((part.failed for part in parts if part.failed is not None), None)
    paths = {world: path for part in parts for world, path in part.paths.items()}
    return Ran(records, failed, paths, parts[0].scale, parts[0].batched)


def _shard(options: dict[str, Any], kwargs: dict[str, Any], chosen: Sequence[int],
           jobs: Sequence[BarnJob], plotted: set[int], cars_for: int) -> Any:
    """A worker's runs (``run``): its own driver and cars."""
    from smartcar_gym.bench import cli

    args = argparse.Namespace(**options)
    # the worker's share of the cores for the vector env's and the driver's compiled loops
    # (more threads than cores only wait on one another; the same records whatever the count)
    share = max(1, (os.cpu_count() or 1) // args.workers)
    driver = cli.driver_for(args, threads=share)[0]
    return cli.run_here(driver, args.n_envs, {**kwargs, "num_threads": share}, chosen, jobs,
                    plotted, args.quiet, cars_for, SHARED)
