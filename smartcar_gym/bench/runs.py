"""Runs of a driver on BARN worlds: the runner's jobs (world, run, seed), and their records.

``run_barn`` hands the jobs to the cars of one vector env through the episode runner
(``agents.runner.run_jobs``: a car whose run ends takes the next job by a partial reset with
its seed and world, a car left without one parked where it stands): the batched env where
the engine batches, else a loop of single envs. The driver is the runner's policy: it is told
of every start (``reset``) and asked for the running cars' actions (``act``, ``act_chunk``
cars at a time), reading the cars through a ``CarView``. Per car the batch is its single env
bit for bit, so the records do not depend on the vector env or on how many cars ran them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.agents.runner import Hooks, Job, JobQueue, one_torch_thread, run_jobs
from smartcar_gym.envs.vector.view import CarView
from smartcar_gym.navigation.grid_planner import NoPathError
from smartcar_gym.worlds.barn import TEST_WORLDS, BarnWorldError

#: the ``info`` keys a run's record reads
RECORD_KEYS = ("outcome", "run_time_s", "score", "score_025", "optimal_time_s", "distance")


@dataclass(frozen=True)
class BarnJob:
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


class BarnRunError(RuntimeError):
    """A run that could not go on (a world without a way for this car): the message says
    which; ``records`` holds the runs that had ended, in the order of the jobs."""

    def __init__(self, message: str, records: list[RunRecord]) -> None:
        super().__init__(message)
        self.records = records


def barn_jobs(worlds: Sequence[int] = TEST_WORLDS, runs: int = 1, seed: int = 0
              ) -> list[BarnJob]:
    """K runs of every world, run k seeded ``seed + k``."""
    return [BarnJob(w, k, seed + k) for w in worlds for k in range(runs)]


class _Records(Hooks):
    """Each run's way and, once it ends, its record (``report``: told of each)."""

    def __init__(self, barn: list[BarnJob], driver: Any, cars: CarView,
                 keep: Callable[[BarnJob], bool], report: Callable[[RunRecord], None] | None
                 ) -> None:
        self.barn, self.driver, self.cars = barn, driver, cars
        self.keep, self.report = keep, report
        self.records: list[RunRecord | None] = [None] * len(barn)
        self.ways: dict[int, list[np.ndarray]] = {}

    def begin(self, envs: gym.vector.VectorEnv, cars: np.ndarray, jobs: list[Job], obs: Any,
              info: dict[str, Any]) -> None:
        for car in cars.tolist():
            self.ways[car] = [np.array(info["pose"][car, :2], dtype=float)]
        self.driver.reset(self.cars, cars.tolist())

    def step(self, cars: np.ndarray, actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> None:
        for car in cars.tolist():
            self.ways[car].append(np.array(info["pose"][car, :2], dtype=float))

    def end(self, car: int, job: Job, info: dict[str, Any]) -> None:
        barn, way = self.barn[job.episode], self.ways[car]
        last = {k: info[k][car] for k in RECORD_KEYS}
        record = RunRecord(barn.world, barn.run, barn.seed, last["outcome"],
                           float(last["run_time_s"]), float(last["score"]),
                           float(last["score_025"]), float(last["optimal_time_s"]),
                           float(last["distance"]), len(way) - 1,
                           np.array(way) if self.keep(barn) else None)
        self.records[job.episode] = record
        if self.report is not None:
            self.report(record)


def run_barn(envs: gym.vector.VectorEnv, driver: Any, jobs: Sequence[BarnJob],
             keep: Callable[[BarnJob], bool] = lambda job: False,
             report: Callable[[RunRecord], None] | None = None,
             shared: Any | None = None) -> list[RunRecord]:
    """Every job's record, in the order of ``jobs``; ``keep(job)``: keep its trajectory;
    ``report``: called as each run ends; ``shared``: the jobs are shared with other
    processes (``runner.JobQueue``), and the records are of the jobs this one took.
    BarnRunError (with the records so far) if a world cannot be run."""
    cars = CarView(envs)
    records = _Records(list(jobs), driver, cars, keep, report)

    def act(obs: Any, running: list[Job | None], steps: np.ndarray) -> np.ndarray:
        actions = np.zeros((cars.num, 2), dtype=np.float32)
        active = [car for car, job in enumerate(running) if job is not None]
        size = getattr(driver, "act_chunk", None) or max(len(active), 1)
        for j in range(0, len(active), size):
            chunk = active[j:j + size]
            actions[chunk] = driver.act(cars, obs[chunk], chunk)
        return actions

    try:
        queue = JobQueue([Job(k, job.seed, {"world": job.world})
                          for k, job in enumerate(jobs)], shared)
        with one_torch_thread():
            run_jobs(envs, queue, act, [records])
    except (BarnWorldError, NoPathError) as err:
        raise BarnRunError(str(err), [r for r in records.records if r is not None]) from None
    return [record for record in records.records if record is not None]
