"""Screenshots of a web page in headless Chromium (Debian's ``chromium``), for the tests and
the docs' picture of Rerun's web viewer.

Chromium is driven through the DevTools protocol over ``--remote-debugging-pipe`` (file
descriptors 3 and 4, NUL-terminated JSON): nothing but the standard library. It runs without
network services (no sync, updates or QUIC) in a fresh profile, with SwiftShader's software
WebGL, which Rerun's viewer needs where there is no GPU.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--mute-audio",
         "--remote-debugging-pipe")


def find_chromium() -> str | None:
    """The Chromium executable on PATH (``chromium``, ``chromium-browser``), or None."""
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


class _Pipe:
    """The DevTools protocol over Chromium's pipe."""

    def __init__(self, write_fd: int, read_fd: int) -> None:
        self._write, self._read = write_fd, read_fd
        self._buffer = b""
        self._id = 0

    def call(self, method: str, session: str | None = None, timeout_s: float = 60.0,
             **params: Any) -> dict[str, Any]:
        self._id += 1
        message: dict[str, Any] = {"id": self._id, "method": method, "params": params}
        if session is not None:
            message["sessionId"] = session
        os.write(self._write, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout_s
        while True:
            reply = self._next(deadline)
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"chromium: {method}: {reply['error']}")
                return reply.get("result", {})

    def _next(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._read, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed its DevTools pipe")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)


def screenshot(url: str, out: str | os.PathLike, *, width: int = 1400, height: int = 800,
               ready: Callable[[np.ndarray], bool] | None = None, timeout_s: float = 120.0,
               every_s: float = 2.0, settle_s: float = 0.0) -> np.ndarray:
    """Open ``url`` and save a PNG of it to ``out`` once ``ready(rgb)`` holds (the first
    screenshot when ``ready`` is None), then ``settle_s`` later; returns that image (H x W x 3).

    TimeoutError after ``timeout_s`` (the last screenshot is saved all the same).
    """
    import imageio.v3 as iio

    executable = find_chromium()
    if executable is None:
        raise FileNotFoundError("chromium not found on PATH (Debian: apt-get install chromium)")
    profile = tempfile.mkdtemp(prefix="smartcar-chromium-")
    to_child, from_parent = os.pipe()
    to_parent, from_child = os.pipe()

    def plumb() -> None:  # in the child: DevTools reads fd 3, writes fd 4
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_child, from_child)]
        os.dup2(high[0], 3)  # out of the way first: the pipes may be fds 3 and 4 themselves
        os.dup2(high[1], 4)

    process = subprocess.Popen(
        [executable, *FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
         "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, pass_fds=(3, 4),
        preexec_fn=plumb)  # noqa: PLW1509 (nothing threaded before exec)
    os.close(to_child)
    os.close(from_child)
    try:
        pipe = _Pipe(from_parent, to_parent)
        target = pipe.call("Target.createTarget", url="about:blank")["targetId"]
        session = pipe.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        pipe.call("Emulation.setDeviceMetricsOverride", session, width=width, height=height,
                  deviceScaleFactor=1, mobile=False)
        pipe.call("Page.navigate", session, url=url)
        deadline = time.monotonic() + timeout_s
        while True:
            time.sleep(every_s)
            data = pipe.call("Page.captureScreenshot", session, format="png")["data"]
            png = base64.b64decode(data)
            image = iio.imread(png)[..., :3]
            done = ready is None or ready(image)
            if done and settle_s > 0:
                time.sleep(settle_s)
                png = base64.b64decode(
                    pipe.call("Page.captureScreenshot", session, format="png")["data"])
                image = iio.imread(png)[..., :3]
            if done or time.monotonic() > deadline:
                Path(out).write_bytes(png)
                if not done:
                    raise TimeoutError(f"{url} was not ready after {timeout_s:g} s; the last "
                                       f"screenshot is {out}")
                return image
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        os.close(from_parent)
        os.close(to_parent)
        shutil.rmtree(profile, ignore_errors=True)


def color_pixels(image: np.ndarray, color: tuple[int, int, int], tolerance: int = 30) -> int:
    """How many pixels of ``image`` are within ``tolerance`` of ``color`` in every channel."""
    close = np.abs(image.astype(int) - np.array(color)) <= tolerance
    return int(np.count_nonzero(close.all(axis=-1)))
