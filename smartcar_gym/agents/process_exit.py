"""Ending a command's process once its work is written, without Python's teardown.

A process that has imported torch spends more than a second after its last line in the
interpreter's teardown, freeing module by module what the operating system is about to take
back whole: the README's ``smartcar-train`` process ended 1.41-1.48 s after its ``main``
returned, 0.08 s with ``exit_now`` (2026-12-01, the 2-core machine; about 5 % of the
training's wall time).

``exit_now`` does what Python's own exit does first, in the same order, and then ends the
process (``os._exit``) instead of tearing the interpreter down:

1. waits for the threads that are not daemons;
2. runs the ``atexit`` functions (logging's shutdown, ``weakref.finalize``'s such as temporary
   directories', multiprocessing's reaping of its children, coverage's data);
3. flushes Python's standard streams and the C library's (pybullet writes with ``printf``).

Nothing a command writes is left unwritten: its files are closed by then (the run's logger
included, ``training.train``). Only the console scripts and ``python -m`` of ``smartcar-train``
and ``smartcar-eval`` call it (``process_start.run_command``), once ``main`` has returned; an
exception leaves the usual way, and code that calls ``main`` (the tests, a notebook) is not
touched.
``SMARTCAR_GYM_FAST_EXIT=0`` ends with ``sys.exit`` instead (for a tool that needs the
teardown).
"""

from __future__ import annotations

import atexit
import ctypes
import os
import sys
import threading
from typing import NoReturn

#: the exit code where a standard stream cannot be flushed at the end (Python's own)
FLUSH_FAILED_EXIT_CODE = 120


def _flush_c_streams() -> None:
    """``fflush(NULL)``: every C ``FILE`` stream of the process (no-op where there is no C
    library to load, as on Windows)."""
    try:
        libc = ctypes.CDLL(None)
    except OSError:
        return
    libc.fflush(None)


def exit_now(code: int | None) -> NoReturn:
    """End the process with ``code`` (None: 0) after the threads, ``atexit`` functions and
    stream flushes that Python's exit would run, skipping the interpreter's teardown."""
    code = 0 if code is None else int(code)
    if os.environ.get("SMARTCAR_GYM_FAST_EXIT", "1") == "0":
        sys.exit(code)
    main = threading.main_thread()
    for thread in threading.enumerate():
        if thread is not main and not thread.daemon:
            thread.join()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        if stream is None or stream.closed:
            continue
        try:
            stream.flush()
        except OSError:  # a pipe closed early (``| head``): Python's exit gives 120 too
            code = FLUSH_FAILED_EXIT_CODE
    _flush_c_streams()
    os._exit(code)
