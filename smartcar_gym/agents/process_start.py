"""Setting up a command's process for its work: settings that change no number, only time.

``start_process`` raises the garbage collector's first threshold from Python's 700 new
container objects to ``YOUNG_THRESHOLD``. Importing torch and Stable-Baselines3 makes
hundreds of thousands of long-lived objects, and with the default each of their many young
collections pushes survivors on until seven full collections scan them all: the README's
training spent 0.91 s in the collector (1,089 young, 99 middle and 7 full collections), 0.39 s
with this threshold (142, 13 and 1; its peak memory 552 MB either way; 2026-12-01, the 2-core
machine). Cyclic garbage is still collected, only in larger batches; reference counting frees
everything else at once, as before.

Only the console scripts and ``python -m`` of ``smartcar-train`` and ``smartcar-eval`` call it,
before ``main`` (as ``process_exit.exit_now`` after it); code that calls ``main`` (the tests,
a notebook) keeps its own settings.
"""

from __future__ import annotations

import gc

#: new container objects between two young collections (Python's default: 700)
YOUNG_THRESHOLD = 10_000


def start_process() -> None:
    """The collector's first threshold at ``YOUNG_THRESHOLD`` (the other two unchanged)."""
    _, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_THRESHOLD, middle, old)
