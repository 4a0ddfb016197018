"""A virtual X display (Xvfb) for the tests of ``render_mode="human"`` (pybullet's GUI,
MuJoCo's viewer): ``needs_xvfb`` skips without it; ``start`` runs one (conftest's ``display``
fixture)."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

needs_xvfb = pytest.mark.skipif(
    shutil.which("Xvfb") is None,
    reason="a window needs a display: apt-get install xvfb (.ci/run does)",
)


@contextmanager
def start() -> Iterator[str]:
    """A fresh Xvfb server, its display name (":N") while it runs; a skip if it fails."""
    server = subprocess.Popen(
        ["Xvfb", "-displayfd", "1", "-screen", "0", "640x480x24", "-nolisten", "tcp"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
    )
    with server.stdout:  # read once: the display's number, written once it is ready
        number = server.stdout.readline().decode().strip()
    if not number.isdigit():
        server.kill()
        pytest.skip(f"Xvfb is installed but did not start (exit {server.wait()})")
    try:
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=10)
