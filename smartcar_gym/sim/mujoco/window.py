"""MuJoCo's own viewer as the env's ``render_mode="human"`` window.

``Window`` opens ``mujoco.viewer.launch_passive`` on the world's compiled model and data: the
viewer draws in its own thread what ``show`` hands it (``Handle.sync``), from an orbit camera
placed as pybullet's GUI camera, with the facade's visual-only markers (goal, odometry trail,
laser hits) in the viewer's user scene. Nothing is simulated by the viewer. When the world is
recompiled (a reset, the Nav obstacles) the viewer is handed the new model and data.

``unavailable()`` says why no viewer can open in this process (macOS outside ``mjpython``, no
GLFW library); ``start_glfw()`` why none can open now (no X or Wayland display, or one that
does not answer): ``launch_passive`` would otherwise wait forever for a window that failed.
"""

from __future__ import annotations

import functools
import os
import sys
import threading
import time
import warnings
from collections.abc import Sequence
from typing import Any

import mujoco

from smartcar_gym.sim.mujoco.body import Marker
from smartcar_gym.sim.mujoco.render import (
    add_markers,
    point_orbit,
    release_glfw,
    show_groups,
    use_glfw,
)

#: how long ``close`` waits for the viewer's thread to destroy its window (s)
CLOSE_TIMEOUT_S = 5.0
#: how long ``start_glfw`` tries to reach the display (s)
START_TIMEOUT_S = 2.0


@functools.cache
def unavailable() -> str | None:
    """Why MuJoCo's viewer cannot open in this process (None: it can)."""
    try:
        import mujoco.viewer
    except (ImportError, RuntimeError, OSError) as exc:  # no GLFW library
        return f"MuJoCo's viewer cannot be loaded ({' '.join(str(exc).split())})"
    if sys.platform == "darwin" and getattr(mujoco.viewer, "_MJPYTHON", None) is None:
        return "on macOS MuJoCo's viewer needs the script run with mjpython"
    return None


def start_glfw() -> None:
    """Start GLFW for one more simulator with a window (``stop_glfw`` when it closes); a
    RuntimeError in one line unless a window can open now (a display that answers).

    GLFW stays started while any such simulator is open, so the viewer's own start is a no-op
    that cannot fail (a failed one in its thread would leave ``launch_passive`` waiting
    forever). It ends when the last window or offscreen renderer using it closes
    (``render.release_glfw``): no connection outlives the windows, and no renderer loses its
    hidden window.
    """
    why = unavailable()
    if why is not None:
        raise RuntimeError(f"render_mode='human' opens MuJoCo's viewer, but {why}; use "
                           "render_mode='rgb_array'")
    display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    if sys.platform.startswith("linux") and not display:
        raise RuntimeError("render_mode='human' opens MuJoCo's viewer, which needs a display "
                           "(DISPLAY is not set); use render_mode='rgb_array' for headless "
                           "rendering")
    import glfw

    use_glfw(lambda: _init_glfw(glfw, display), window=True)


def _init_glfw(glfw: Any, display: str | None) -> None:
    deadline = time.monotonic() + START_TIMEOUT_S
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # an X server that lost its last client resets, refusing connections for a moment
        while not glfw.init():
            if time.monotonic() > deadline:
                raise RuntimeError(f"render_mode='human' opens MuJoCo's viewer, but GLFW "
                                   f"cannot start on display {display!r} ({_said(caught)}); use "
                                   "render_mode='rgb_array'")
            time.sleep(0.01)
        # a display without OpenGL: the viewer's thread would fail to make its window
        glfw.window_hint(glfw.VISIBLE, glfw.FALSE)
        probe = glfw.create_window(1, 1, "smartcar_gym", None, None)
        glfw.default_window_hints()
        if not probe:
            glfw.terminate()
            raise RuntimeError(f"render_mode='human' opens MuJoCo's viewer, but display "
                               f"{display!r} has no OpenGL window for it ({_said(caught)}); use "
                               "render_mode='rgb_array'")
        glfw.destroy_window(probe)


def _said(caught: list[warnings.WarningMessage]) -> str:
    """What GLFW reported (its errors arrive as warnings), on one line."""
    lines = dict.fromkeys(" ".join(str(w.message).split()) for w in caught)
    return "; ".join(lines) or "no reason given"


def stop_glfw() -> None:
    """One simulator with a window less; GLFW ends with its last window or renderer."""
    release_glfw()


class Window:
    """One viewer window, opened at the first ``show`` and closed by ``close``."""

    def __init__(self) -> None:
        self._handle = None
        self._threads: list[threading.Thread] = []
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None

    @property
    def is_open(self) -> bool:
        """Whether the window is open (the user may have closed it)."""
        return self._handle is not None and self._handle.is_running()

    @property
    def camera(self) -> mujoco.MjvCamera | None:
        """The viewer's camera (None before the window opens)."""
        return None if self._handle is None else self._handle.cam

    @property
    def scene(self) -> mujoco.MjvScene | None:
        """The viewer's user scene: the markers drawn over the world."""
        return None if self._handle is None else self._handle.user_scn

    @property
    def model(self) -> mujoco.MjModel | None:
        """The model the viewer draws."""
        return self._model

    def show(self, model: mujoco.MjModel, data: mujoco.MjData, markers: Sequence[Marker],
             target: Sequence[float], distance: float, yaw_deg: float, pitch_deg: float,
             show_collision: bool = False, fov_deg: float = 50.0) -> None:
        """Draw ``data`` from an orbit camera (pybullet's GUI camera for the same arguments),
        with the markers; opens the window the first time. A window the user closed stays
        closed."""
        if self._handle is None:
            self._open(model, data)
        elif not self._handle.is_running():
            return
        elif model is not self._model:
            viewer = self._handle._sim()
            if viewer is None:  # closed by the user since
                return
            viewer.load(model, data, "")  # as the viewer's own reload does
            self._model, self._data = model, data
        handle = self._handle
        model.vis.global_.fovy = fov_deg
        with handle.lock():
            show_groups(handle.opt, show_collision)
            point_orbit(handle.cam, target, distance, yaw_deg, pitch_deg)
            scene = handle.user_scn
            scene.ngeom = 0
            add_markers(scene, markers)
        handle.sync()

    def _open(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        import mujoco.viewer

        before = set(threading.enumerate())
        self._handle = mujoco.viewer.launch_passive(model, data, show_left_ui=False,
                                                    show_right_ui=False)
        self._threads = [t for t in threading.enumerate() if t not in before]
        self._model, self._data = model, data
        self._handle.cam.type = mujoco.mjtCamera.mjCAMERA_FREE

    def close(self) -> None:
        """Close the window and wait for its thread to destroy it (idempotent)."""
        handle, self._handle = self._handle, None
        if handle is None:
            return
        handle.close()
        for thread in self._threads:
            thread.join(CLOSE_TIMEOUT_S)
        self._threads = []
        self._model = self._data = None
