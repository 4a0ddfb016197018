"""Compiled loops over robots, split across threads: ``run_chunks(work, n, threads)`` calls
``work(start, stop)`` on consecutive chunks of ``range(n)``, ``threads`` at once (each thread
takes the next chunk when its last is done), and waits until every chunk is done (not for a
thread that found none left).

The loops are numba's with ``nogil=True``, each robot's work independent of the others' and
written to its own rows, so a split run gives the numbers of one call bit for bit; numba's own
``parallel=True`` is not used (its default threading layer aborts when two Python threads
enter it at once). One pool serves the process; a thread count of 1, or too few robots
for two chunks (``MIN_CHUNK``, or the caller's ``min_chunk``), runs in the calling thread.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

MIN_CHUNK = 4  # robots per chunk below which splitting costs more than it saves (by default)
#: chunks per thread, taken in turn: a thread whose robots cost less takes more of them (the
#: robots' costs differ: a DWA robot among many obstacle points costs several times another's)
CHUNKS_PER_THREAD = 4
_POOL: ThreadPoolExecutor | None = None
_POOL_PID = 0  # the process that made it: a forked child makes its own (it has no threads)
_POOL_LOCK = threading.Lock()


def run_chunks(work: Callable[[int, int], None], n: int, threads: int,
               min_chunk: int = MIN_CHUNK) -> None:
    """``work(start, stop)`` over ``range(n)`` on at most ``threads`` threads in parallel, in
    up to ``CHUNKS_PER_THREAD`` chunks per thread of ``min_chunk`` robots or more (a split
    costs some 20-40 us: cheap robots need many to a chunk); the first chunk's error (by
    robot) is raised once every chunk has run."""
    parts = max(1, min(threads, n // min_chunk))
    if parts == 1:
        work(0, n)
        return
    pieces = max(parts, min(parts * CHUNKS_PER_THREAD, n // min_chunk))
    bounds = [n * k // pieces for k in range(pieces + 1)]
    taken = itertools.count()  # the next chunk: ``next`` on it is atomic (one C call)
    finished = itertools.count(1)
    all_done = threading.Event()
    errors: dict[int, BaseException] = {}

    def drain() -> None:
        while (k := next(taken)) < pieces:
            try:
                work(bounds[k], bounds[k + 1])
            except BaseException as error:  # raised in the calling thread
                errors[k] = error
            if next(finished) == pieces:
                all_done.set()

    for _ in range(parts - 1):
        _pool().submit(drain)
    drain()  # the calling thread takes chunks too
    # waits for the chunks, not for the threads: a thread the system wakes only once the
    # caller has taken every chunk (a busy machine) costs nothing
    all_done.wait()
    if errors:
        raise errors[min(errors)]


def _pool() -> ThreadPoolExecutor:
    global _POOL, _POOL_PID
    with _POOL_LOCK:
        if _POOL is None or _POOL_PID != os.getpid():
            _POOL = ThreadPoolExecutor(max_workers=max(1, (os.cpu_count() or 1) - 1),
                                       thread_name_prefix="smartcar-gym-loops")
            _POOL_PID = os.getpid()
        return _POOL
