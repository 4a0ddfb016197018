"""The one episode runner: jobs (an episode's seed and reset options) handed to the cars of a
vector env, in turn.

``run_jobs`` keeps every car busy: the cars start the first jobs, and a car whose episode
ends takes the next job not started yet at once (Gymnasium's partial reset,
``reset(seed=[...], options={"reset_mask": mask, ...})``); a car with no job left is parked
where the vector env can (``park``: not simulated), else stepped with zero actions and not
read. So the records do not depend on how many cars ran them. The jobs not started yet are a
``JobQueue``: one runner's, or one shared by the runners of several processes (``shared``),
each car taking the next job of all as it frees. What happens along the way is
the hooks' (``Hooks``): the evaluations' records, the benchmark's runs, a classical
driver's start, captured frames, dataset steps. Every evaluation, the benchmark, videos and
bags run their episodes here.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

#: ``act(obs, jobs, steps)``: every car's action ((N, 2) float32) from the batch of
#: observations, the job each car runs (None: none) and the steps its episode has run
Act = Callable[[Any, list["Job | None"], np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Job:
    """One episode to run: its index among the jobs, its reset's seed and options."""

    episode: int
    seed: int | None
    options: Mapping[str, Any] | None = None


class JobQueue:
    """The jobs not started yet, taken in their order. ``shared``: a
    ``multiprocessing.Value`` (an integer, 0 at first) that several processes' queues of the
    same jobs share, the index of the next job not taken by any: each process's cars take
    the next jobs of all as they free, so none waits while another still has a backlog (a
    fixed share each, one process can be left running alone at the end)."""

    def __init__(self, jobs: Sequence[Job], shared: Any | None = None) -> None:
        self.jobs = list(jobs)
        self.shared = shared
        self._next = 0

    def take(self, k: int) -> list[Job]:
        """The next ``k`` jobs (fewer where fewer are left)."""
        if self.shared is None:
            start = self._next
            self._next = stop = min(start + k, len(self.jobs))
        else:
            with self.shared.get_lock():
                start = self.shared.value
                self.shared.value = stop = min(start + k, len(self.jobs))
        return self.jobs[start:stop]


class Hooks:
    """What a caller does along the episodes (each method does nothing here)."""

    def begin(self, envs: gym.vector.VectorEnv, cars: np.ndarray, jobs: list[Job], obs: Any,
              info: dict[str, Any]) -> None:
        """The listed cars have just been reset for ``jobs`` (``obs``, ``info``: the reset's,
        every car's observation, the reset cars' info)."""

    def step(self, cars: np.ndarray, actions: np.ndarray, obs: Any, reward: np.ndarray,
             terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> None:
        """One step of the listed cars (those running a job)."""

    def end(self, car: int, job: Job, info: dict[str, Any]) -> None:
        """Car ``car``'s job ended at this step (``info``: the step's, every car's)."""


@contextlib.contextmanager
def one_torch_thread() -> Iterator[None]:
    """torch on one thread while a batch runs: its intra-op threads, idle-spinning beside
    the batch's worker threads, made predict on 16 cars take 10 ms instead of 0.2 ms (and
    100 cars' 3.8 ms instead of 0.6 in ``smartcar-bench barn``). The shipped policies act
    the same on one thread as on two (the benchmark's 500 records are unchanged)."""
    torch = sys.modules.get("torch")
    if torch is None:
        yield
        return
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


class ResetError(ValueError):
    """A vector env that cannot reset single cars (``reset_mask``), which the runner needs."""


def run_jobs(envs: gym.vector.VectorEnv, jobs: Sequence[Job] | JobQueue, act: Act,
             hooks: Sequence[Hooks] = (), check_resets: bool = False,
             stop: Callable[[], bool] | None = None) -> None:
    """Run every job (of a ``JobQueue``: every job this process takes) on the cars of
    ``envs`` (see the module); ``check_resets``: one line
    (``ResetError``) if the vector env resets other cars than it is asked to; ``stop``:
    asked after every step, True ends the run there (the jobs running are left as they
    are)."""
    n = envs.num_envs
    queue = jobs if isinstance(jobs, JobQueue) else JobQueue(jobs)
    running: list[Job | None] = [None] * n
    for car, job in enumerate(queue.take(n)):
        running[car] = job
    first = [job for job in running if job is not None]
    obs, info = envs.reset(seed=[None if j is None else j.seed for j in running],
                           options=_options(running, first, np.ones(n, dtype=bool)))
    active = np.array([job is not None for job in running])  # the cars with a job
    started = np.flatnonzero(active)
    for hook in hooks:
        hook.begin(envs, started, [running[i] for i in started], obs, info)
    steps = np.zeros(n, dtype=np.int64)
    park = getattr(envs.unwrapped, "park", None)
    while active.any():
        actions = act(obs, running, steps)
        if park is not None:  # where the env can, a car with no job is not simulated
            park(~active)
        obs, reward, terminated, truncated, info = envs.step(actions)
        steps[active] += 1
        cars = np.flatnonzero(active)
        for hook in hooks:
            hook.step(cars, actions, obs, reward, terminated, truncated, info)
        if stop is not None and stop():
            return
        done = active & (terminated | truncated)
        if not done.any():
            continue
        for car in np.flatnonzero(done).tolist():
            for hook in hooks:
                hook.end(car, running[car], info)
            running[car] = None
        active &= ~done
        new = queue.take(int(done.sum()))
        if not new:
            continue  # the cars left without a job are not read again
        refill = np.flatnonzero(done)[:len(new)]
        mask = np.zeros(n, dtype=bool)
        mask[refill] = True
        for car, job in zip(refill.tolist(), new, strict=True):
            running[car] = job
        active[refill] = True
        steps[refill] = 0
        new_obs, new_info = _partial_reset(envs, running, new, mask, check_resets)
        obs = _merge(obs, new_obs, mask)
        for hook in hooks:
            hook.begin(envs, refill, new, obs, new_info)


def _options(running: list[Job | None], reset: list[Job], mask: np.ndarray
             ) -> dict[str, Any] | None:
    """The vector reset's options for the ``reset`` jobs: one value when they share it, else
    one per car (the cars not reset get the first job's); with ``reset_mask`` unless every
    car is reset."""
    options: dict[str, Any] = {}
    first = reset[0].options or {} if reset else {}
    for key in {k for job in reset for k in (job.options or {})}:
        values = [(job.options or {}).get(key) for job in reset]
        if all(_same(v, values[0]) for v in values):
            options[key] = values[0]
        else:
            options[key] = [(job.options or {}).get(key) if job is not None and m
                             else first.get(key) for job, m in zip(running, mask, strict=True)]
    if not mask.all():
        options["reset_mask"] = mask
    return options or None


def _same(a: Any, b: Any) -> bool:
    return a is b or (np.shape(a) == np.shape(b) and bool(np.all(np.asarray(a) == b)))


def _partial_reset(envs: gym.vector.VectorEnv, running: list[Job | None], new: list[Job],
                   mask: np.ndarray, check: bool) -> tuple[Any, dict[str, Any]]:
    """Reset the masked cars for their new jobs; with ``check``, one line if the vector env
    cannot (a vector entry point that ignores the mask)."""
    seeds = [job.seed if m and job is not None else None
             for job, m in zip(running, mask, strict=True)]
    options = _options(running, new, mask)
    if not check:
        return envs.reset(seed=seeds, options=options)
    what = (f"vector env ({type(envs.unwrapped).__name__}) cannot reset single cars "
            "(reset(options={'reset_mask': mask}), Gymnasium's partial reset)")
    try:
        obs, info = envs.reset(seed=seeds, options=options)
    except (ValueError, TypeError, KeyError, AssertionError) as err:
        raise ResetError(f"{what}: {err}") from err
    reset = info.get("_pose")
    if reset is None or not np.array_equal(reset, mask):
        raise ResetError(f"{what}: it reset cars {np.flatnonzero(reset).tolist()}, not "
                         f"{np.flatnonzero(mask).tolist()}")
    return obs, info


def _merge(obs: Any, new: Any, mask: np.ndarray) -> Any:
    """The batch of observations with the masked cars' from ``new`` (a dict of batches for a
    ``Dict`` space)."""
    if isinstance(obs, Mapping):
        for key in obs:
            obs[key][mask] = new[key][mask]
        return obs
    obs[mask] = new[mask]
    return obs
