"""Quiet access to pybullet: one ``BulletClient`` per caller, without the C-level banners.

pybullet writes ``pybullet build time: ...`` to the C stderr when it is imported and
``argv[0]=`` lines when a client connects. We point the process's file descriptors 1 and 2 at
/dev/null around those two moments only, so our CLIs, tests and ``gym.make`` stay clean.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator

try:
    _libc = ctypes.CDLL(None)
except OSError:  # pragma: no cover - platforms without a loadable C library
    _libc = None


def _flush_all() -> None:
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    if _libc is not None:  # C stdio buffers stdout when it is a pipe
        with contextlib.suppress(Exception):
            _libc.fflush(None)


@contextlib.contextmanager
def silenced_output() -> Iterator[None]:
    """Send the C-level stdout and stderr (fds 1 and 2) to /dev/null for the block."""
    _flush_all()
    saved: list[tuple[int, int]] = []
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            with contextlib.suppress(OSError):
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
        yield
    finally:
        _flush_all()
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


with silenced_output():
    import pybullet  # noqa: E402
    import pybullet_data  # noqa: E402
    from pybullet_utils import bullet_client  # noqa: E402


def connect(gui: bool = False, options: str = "") -> bullet_client.BulletClient:
    """Open a new ``BulletClient`` (DIRECT unless ``gui``), never the global pybullet client."""
    with silenced_output():
        mode = pybullet.GUI if gui else pybullet.DIRECT
        client = bullet_client.BulletClient(connection_mode=mode, options=options)
    client.setAdditionalSearchPath(pybullet_data.getDataPath())
    return client


__all__ = ["bullet_client", "connect", "pybullet", "pybullet_data", "silenced_output"]
