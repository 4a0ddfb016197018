"""Runs of a driver on BARN worlds: jobs (world, run, seed) handed to a row of envs in step.

``run_barn`` keeps every env busy: each steps with the others (one ``driver.act`` for all)
and takes the next job when its run ends. The row is single envs (any engine);
``bench.batched.run_barn_vector`` runs the same jobs on one batched env.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from smartcar_gym.worlds.barn import TEST_WORLDS


@dataclass(frozen=True)
class Job:
    """Run ``run`` of world ``world``, its env reset with ``seed``."""

    world: int
    run: int
    seed: int


@dataclass
class RunRecord:
    """How one run ended (``info`` of its last step) and, if kept, its way (ground truth)."""

    world: int
    run: int
    seed: int
    outcome: str | None
    time_s: float
    score: float
    score_025: float
    optimal_time_s: float
    final_distance_m: float
    steps: int
    trajectory: np.ndarray | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The record without its trajectory (what the JSON holds)."""
        out = asdict(self)
        out.pop("trajectory")
        return out


def barn_jobs(worlds: Sequence[int] = TEST_WORLDS, runs: int = 1, seed: int = 0) -> list[Job]:
    """K runs of every world, run k seeded ``seed + k``."""
    return [Job(w, k, seed + k) for w in worlds for k in range(runs)]


def run_barn(envs: Sequence[Any], driver: Any, jobs: Sequence[Job],
             keep: Callable[[Job], bool] = lambda job: False,
             report: Callable[[RunRecord], None] | None = None) -> list[RunRecord]:
    """Every job's record, in the order of ``jobs``; ``keep(job)``: keep its trajectory;
    ``report``: called as each run ends."""
    queue = list(enumerate(jobs))
    records: list[RunRecord | None] = [None] * len(jobs)
    slots: list[tuple[int, Job, list] | None] = [None] * len(envs)
    obs: list[Any] = [None] * len(envs)

    def start(i: int) -> None:
        if not queue:
            slots[i] = None
            return
        index, job = queue.pop(0)
        obs[i], info = envs[i].reset(seed=job.seed, options={"world": job.world})
        slots[i] = (index, job, [info["pose"][:2]])
        driver.reset(envs, [i])

    for i in range(len(envs)):
        start(i)
    while any(slot is not None for slot in slots):
        active = [i for i, slot in enumerate(slots) if slot is not None]
        actions = driver.act([envs[i] for i in active], np.stack([obs[i] for i in active]),
                             active)
        for i, action in zip(active, actions, strict=True):
            obs[i], _, terminated, truncated, info = envs[i].step(action)
            index, job, way = slots[i]
            way.append(info["pose"][:2])
            if terminated or truncated:
                records[index] = record_of(job, info, way, keep(job))
                if report is not None:
                    report(records[index])
                start(i)
    return records


def record_of(job: Job, info: dict[str, Any], way: list, keep: bool) -> RunRecord:
    """The record of ``job`` from its last step's ``info`` and its ``way`` (poses)."""
    return RunRecord(job.world, job.run, job.seed, info["outcome"], float(info["run_time_s"]),
                     float(info["score"]), float(info["score_025"]),
                     float(info["optimal_time_s"]), float(info["distance"]), len(way) - 1,
                     np.array(way) if keep else None)
