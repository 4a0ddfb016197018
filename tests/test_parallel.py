"""``parallel.run_chunks``: compiled loops over robots split across threads give one call's
numbers, every robot once, and a chunk's error reaches the caller."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from smartcar_gym import parallel
from smartcar_gym.navigation.footprint import COMPILED, footprint_check
from smartcar_gym.parallel import CHUNKS_PER_THREAD, MIN_CHUNK, run_chunks


@pytest.mark.parametrize("n, threads, min_chunk, chunks", [
    (0, 2, MIN_CHUNK, 1), (7, 2, MIN_CHUNK, 1), (8, 2, MIN_CHUNK, 2), (23, 3, MIN_CHUNK, 5),
    (9, 1, MIN_CHUNK, 1), (100, 4, MIN_CHUNK, 16), (2047, 2, 1024, 1), (4096, 2, 1024, 4)])
def test_every_robot_is_worked_once_in_consecutive_chunks(n, threads, min_chunk, chunks):
    """Up to ``CHUNKS_PER_THREAD`` chunks per thread, none under ``min_chunk`` robots, on at
    most ``threads`` threads; one thread (the caller's) below two chunks' worth."""
    seen = np.zeros(n, dtype=int)
    done, names = [], set()

    def work(a: int, b: int) -> None:
        seen[a:b] += 1
        done.append((a, b))
        names.add(threading.current_thread().name)

    run_chunks(work, n, threads, min_chunk)
    assert (seen == 1).all() and len(done) == chunks
    assert all(b - a >= min(n, min_chunk) for a, b in done)
    assert len(names) <= threads and (chunks > 1 or names == {threading.current_thread().name})


def test_a_thread_whose_chunk_is_slow_leaves_the_others_to_the_other_threads():
    """Chunks are taken in turn: while the first chunk's robot takes long, the other thread
    works every other chunk (a fixed split would leave it half the robots, then idle)."""
    by_thread: dict[str, list[int]] = {}

    def work(a: int, b: int) -> None:
        if a == 0:
            time.sleep(0.5)
        by_thread.setdefault(threading.current_thread().name, []).append(a)

    run_chunks(work, 32, 2)
    assert sorted(len(v) for v in by_thread.values()) == [1, CHUNKS_PER_THREAD * 2 - 1]
    assert [0] in by_thread.values()


def test_a_chunks_error_reaches_the_caller():
    def work(a: int, b: int) -> None:
        if a > 0:
            raise ValueError(f"robot {a} has no scan")

    with pytest.raises(ValueError, match="robot 4 has no scan"):
        run_chunks(work, 8, 2)


def test_the_caller_does_not_wait_for_a_thread_that_found_no_chunk():
    """On a busy machine a worker may start only after the caller has taken every chunk:
    the call returns once the chunks are done, not when that worker gets to run."""
    pool, release = parallel._pool(), threading.Event()
    for _ in range(pool._max_workers):  # every worker busy
        pool.submit(release.wait)
    done: list[int] = []
    caller = threading.Thread(target=run_chunks, args=(lambda a, b: done.append(a), 32, 2))
    try:
        caller.start()
        caller.join(timeout=10)
        assert not caller.is_alive() and len(done) == CHUNKS_PER_THREAD * 2
    finally:
        release.set()


@pytest.mark.skipif(not COMPILED, reason="numba (the fast extra) is off or not installed")
def test_the_footprint_check_split_over_threads_is_one_calls():
    rng = np.random.default_rng(2)
    n, c, t, p = 12, 20, 10, 80
    poses = rng.uniform(-0.5, 0.5, (n, c, t, 3))
    points = rng.uniform(-0.8, 0.8, (n, p, 2))
    counts = rng.integers(0, p + 1, n)
    args = (poses, np.cos(poses[..., 2]), np.sin(poses[..., 2]), points, counts, 0.1, 0.06,
            0.25)
    one = footprint_check(*args, compiled=True, threads=1)
    split = footprint_check(*args, compiled=True, threads=3)
    assert np.array_equal(one[0], split[0]) and np.array_equal(one[1], split[1])
    assert 0 < one[0].sum() < one[0].size


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_forked_child_runs_its_chunks_instead_of_waiting_on_the_parents_threads():
    """A process forked after the pool started (a SubprocVecEnv worker) has none of its
    threads: it makes a pool of its own instead of hanging on the parent's."""
    run_chunks(lambda a, b: None, 16, 2)  # the parent's pool is up
    pid = os.fork()
    if pid == 0:  # the child: exit 0 only if the split run finishes
        done = []
        try:
            run_chunks(lambda a, b: done.append((a, b)), 16, 2)
        finally:
            os._exit(0 if sum(b - a for a, b in done) == 16 and len(done) > 1 else 1)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        finished, status = os.waitpid(pid, os.WNOHANG)
        if finished:
            assert os.waitstatus_to_exitcode(status) == 0
            return
        time.sleep(0.05)
    os.kill(pid, 9)
    os.waitpid(pid, 0)
    pytest.fail("the forked child hung on the parent's pool")
