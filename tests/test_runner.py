"""The one episode runner (agents/runner.py): which car runs which job, what each reset asks,
the hooks' calls, parking and stopping; and the cars' public state it reads (envs/state.py)."""

from __future__ import annotations

import multiprocessing
from typing import Any

import numpy as np
import pytest

from smartcar_gym.agents.runner import Hooks, Job, JobQueue, ResetError, one_torch_thread, run_jobs
from smartcar_gym.envs.state import CarState


class FakeCars:
    """A vector env whose car i's episode k ends after ``lengths[k]`` steps (k: the job it
    runs, read from the reset's options), recording every reset and park."""

    def __init__(self, num: int, lengths: dict[int, int], mask_info: bool = True) -> None:
        self.num_envs = num
        self.lengths = lengths
        self.resets: list[tuple[list, dict | None]] = []
        self.parks: list[list[int]] = []
        self.job = [-1] * num
        self.left = [0] * num
        self.mask_info = mask_info
        self.unwrapped = self

    def park(self, mask: np.ndarray) -> None:
        self.parks.append(np.flatnonzero(mask).tolist())

    def reset(self, seed: list, options: dict | None = None) -> tuple[np.ndarray, dict]:
        self.resets.append((list(seed), None if options is None else dict(options)))
        mask = (options or {}).get("reset_mask", np.ones(self.num_envs, dtype=bool))
        jobs = (options or {}).get("job")
        for car in np.flatnonzero(mask):
            job = jobs[car] if isinstance(jobs, list) else jobs
            self.job[car], self.left[car] = job, self.lengths.get(job, 0)
        info = {"_pose": mask.copy() if self.mask_info else ~mask}
        return np.array(self.job, dtype=float).reshape(-1, 1), info

    def step(self, actions: np.ndarray) -> tuple:
        self.left = [n - 1 for n in self.left]
        done = np.array([n == 0 for n in self.left])
        return (np.array(self.job, dtype=float).reshape(-1, 1), np.ones(self.num_envs), done,
                np.zeros(self.num_envs, dtype=bool), {})


class Calls(Hooks):
    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def begin(self, envs: Any, cars: np.ndarray, jobs: list[Job], obs: Any, info: Any) -> None:
        self.calls.append(("begin", cars.tolist(), [j.episode for j in jobs]))

    def step(self, cars: np.ndarray, *rest: Any) -> None:
        self.calls.append(("step", cars.tolist()))

    def end(self, car: int, job: Job, info: Any) -> None:
        self.calls.append(("end", car, job.episode))


def _act(obs: Any, running: list, steps: np.ndarray) -> np.ndarray:
    return np.zeros((len(running), 2), dtype=np.float32)


def test_each_car_takes_the_next_job_when_its_own_ends():
    # jobs 0..4 (episode k lasts lengths[k] steps) on 2 cars
    envs = FakeCars(2, {0: 2, 1: 1, 2: 3, 3: 1, 4: 1})
    jobs = [Job(k, 10 + k, {"job": k}) for k in range(5)]
    hook = Calls()
    run_jobs(envs, jobs, _act, [hook], check_resets=True)
    first_seeds, first_options = envs.resets[0]
    assert first_seeds == [10, 11]
    assert first_options == {"job": [0, 1]}  # differing options: one per car
    # step 1 ends job 1 (car 1), which takes job 2 with its seed; job 0 ends at step 2 ...
    seeds, options = envs.resets[1]
    assert seeds == [None, 12] and options["job"] == 2  # one job: its value
    assert options["reset_mask"].tolist() == [False, True]
    # step 2 ends job 0 (car 0 takes job 3), step 3 job 3 (car 0 takes job 4), step 4 jobs 4
    # and 2 together, told in car order
    assert [c for c in hook.calls if c[0] == "end"] == [
        ("end", 1, 1), ("end", 0, 0), ("end", 0, 3), ("end", 0, 4), ("end", 1, 2)]
    assert hook.calls[0] == ("begin", [0, 1], [0, 1])
    assert [c for c in hook.calls if c[0] == "begin"][1:] == [
        ("begin", [1], [2]), ("begin", [0], [3]), ("begin", [0], [4])]
    assert envs.parks == [[], [], [], []]  # every car had a job at every step


def test_jobs_that_share_options_reset_with_one_value():
    envs = FakeCars(3, {5: 1})
    run_jobs(envs, [Job(k, k, {"job": 5}) for k in range(3)], _act)
    assert envs.resets[0] == ([0, 1, 2], {"job": 5})


def test_fewer_jobs_than_cars_and_a_stop():
    envs = FakeCars(3, {0: 4})
    hook = Calls()
    steps = []
    run_jobs(envs, [Job(0, 7, {"job": 0})], _act, [hook],
             stop=lambda: steps.append(1) or len(steps) == 2)
    assert envs.resets[0][0] == [7, None, None]
    assert envs.parks == [[1, 2], [1, 2]]  # the cars with no job never step
    assert [c for c in hook.calls if c[0] == "step"] == [("step", [0]), ("step", [0])]
    assert not any(c[0] == "end" for c in hook.calls)  # stopped before the job ended


def test_queues_that_share_an_index_hand_out_each_job_once_in_order():
    jobs = [Job(k, k) for k in range(6)]
    shared = multiprocessing.get_context("spawn").Value("q", 0)
    a, b = JobQueue(jobs, shared), JobQueue(jobs, shared)
    assert [j.episode for j in a.take(2)] == [0, 1]
    assert [j.episode for j in b.take(3)] == [2, 3, 4]
    assert [j.episode for j in a.take(4)] == [5]  # fewer where fewer are left
    assert b.take(1) == [] and a.take(1) == [] and shared.value == 6
    alone = JobQueue(jobs)  # no index shared: every job, its own count
    assert [j.episode for j in alone.take(4)] == [0, 1, 2, 3] and shared.value == 6


def test_a_runner_skips_the_jobs_another_process_took():
    # car 1's job 1 ends at step 1; meanwhile "another process" (a second queue of the same
    # jobs and index) takes job 2, so car 1 goes on with job 3
    jobs = [Job(k, k, {"job": k}) for k in range(5)]
    shared = multiprocessing.get_context("spawn").Value("q", 0)
    other = JobQueue(jobs, shared)
    taken: list[int] = []

    class Meanwhile(Calls):
        def step(self, cars: np.ndarray, *rest: Any) -> None:
            super().step(cars, *rest)
            if not taken:
                taken.extend(j.episode for j in other.take(1))

    hook = Meanwhile()
    run_jobs(FakeCars(2, {0: 3, 1: 1, 2: 1, 3: 1, 4: 1}), JobQueue(jobs, shared), _act, [hook])
    assert taken == [2]
    assert [c for c in hook.calls if c[0] == "begin"] == [
        ("begin", [0, 1], [0, 1]), ("begin", [1], [3]), ("begin", [1], [4])]
    assert sorted(c[2] for c in hook.calls if c[0] == "end") == [0, 1, 3, 4]


def test_a_vector_env_that_resets_other_cars_is_one_line():
    envs = FakeCars(2, {0: 1, 1: 2, 2: 1}, mask_info=False)
    with pytest.raises(ResetError, match=r"cannot reset single cars .* it reset cars \[1\], "
                                         r"not \[0\]"):
        run_jobs(envs, [Job(k, k, {"job": k}) for k in range(3)], _act, check_resets=True)


def test_a_state_row_is_copied_whole_and_states_stack():
    a = CarState.zeros(2, 4, {"scan": ((3,), np.float32), "scan_time_ns": ((), np.int64)})
    b = CarState.zeros(1, 4, {"scan": ((3,), np.float32), "scan_time_ns": ((), np.int64)})
    b.pose[0] = (1.0, 2.0, 0.5)
    b.goal[0] = (3.0, -1.0)
    b.readings["scan"][0] = (0.5, np.inf, -np.inf)
    b.readings["scan_time_ns"][0] = 100
    b.parked[0] = True
    a.take(1, b)
    assert a.pose[1].tolist() == [1.0, 2.0, 0.5] and a.goal[1].tolist() == [3.0, -1.0]
    assert a.readings["scan"][1].tolist() == [0.5, np.inf, -np.inf]
    assert a.readings["scan_time_ns"][1] == 100 and a.parked[1]
    assert a.pose[0].tolist() == [0.0, 0.0, 0.0]
    both = CarState.stack([b, a.rows([1])])
    assert both.num == 2 and both.pose.tolist() == [[1.0, 2.0, 0.5]] * 2
    assert both.previous_action.dtype == np.float32 and both.readings["scan"].shape == (2, 3)


def test_one_torch_thread_holds_torch_to_one_thread_and_gives_the_count_back():
    """A batch's predict calls run on one torch thread (its idle-spinning intra-op threads
    slowed the batch's own worker threads); the count is given back, also after an error."""
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        with one_torch_thread():
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
        with pytest.raises(RuntimeError, match="boom"), one_torch_thread():
            raise RuntimeError("boom")
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
