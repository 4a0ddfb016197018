"""One command timed as the speed benchmarks time it (``eval_speed.py``, ``barn_speed.py``),
and the other commit they compare against (``versus.py``, ``barn_speed.py --base``)."""

from __future__ import annotations

import os
import resource
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def worktree_at(root: Path, commit: str) -> Iterator[Path]:
    """A temporary git worktree of ``root``'s repository at ``commit``, removed afterwards."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(root), "worktree", "add", "-q", "--detach", str(path),
                        commit], check=True)
        try:
            yield path
        finally:
            subprocess.run(["git", "-C", str(root), "worktree", "remove", "--force", str(path)],
                           check=False)


def timed_run(argv: list[str], env: dict[str, str] | None = None,
              cwd: str | None = None) -> dict[str, float]:
    """Run ``argv`` (its output discarded; an error exit raises; ``env`` and ``cwd``: its
    environment and folder, as ``subprocess.run``'s): its wall seconds, its CPU
    seconds (the process and its threads and children, from ``getrusage``) and the load
    average before it."""
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, env=env, cwd=cwd)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "load": load}
