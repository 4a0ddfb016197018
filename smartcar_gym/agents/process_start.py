"""Setting up a command's process for its work: settings that change no number, only time.

``start_process`` raises the garbage collector's first threshold from Python's 700 new
container objects to ``YOUNG_THRESHOLD``. Importing torch and Stable-Baselines3 makes
hundreds of thousands of long-lived objects, and with the default each of their many young
collections pushes survivors on until seven full collections scan them all: the README's
training spent 0.91 s in the collector (1,089 young, 99 middle and 7 full collections), 0.39 s
with this threshold (142, 13 and 1; its peak memory 552 MB either way; 2026-12-01, the 2-core
machine). Cyclic garbage is still collected, only in larger batches; reference counting frees
everything else at once, as before.

``run_command`` is a command's whole process: ``start_process``, its ``main``, then
``process_exit.exit_now``. Only the console scripts and ``python -m`` of ``smartcar-train`` and
``smartcar-eval`` go through it; code that calls ``main`` (the tests, a notebook) keeps its own
settings and its own exit.
"""

from __future__ import annotations

import gc
from collections.abc import Callable
from typing import NoReturn

from smartcar_gym.agents.process_exit import exit_now

#: new container objects between two young collections (Python's default: 700)
YOUNG_THRESHOLD = 10_000


def start_process() -> None:
    """The collector's first threshold at ``YOUNG_THRESHOLD`` (the other two unchanged)."""
    _, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_THRESHOLD, middle, old)


def run_command(main: Callable[[], int | None]) -> NoReturn:
    """A command's process: set up (``start_process``), ``main``, then ended with its exit
    code without Python's teardown (``process_exit.exit_now``)."""
    start_process()
    exit_now(main())
