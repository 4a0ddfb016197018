"""The MuJoCo engine behind the simulator facade (the ``mujoco`` extra).

``model`` builds the ``MjSpec`` of one robot from its URDF (reusable for batched worlds),
``simulator`` is ``MujocoSimulator`` (the clock, stepping, the world's spec, model and data),
``body`` the ``Body`` handles and the visual-only markers, ``render`` the offscreen camera.
Importing this package imports ``mujoco``.

Headless rendering: MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when ``mujoco`` is first
imported. Without a display and without ``MUJOCO_GL`` set, this package sets it to ``egl`` if
the EGL library is installed, else to ``osmesa`` if OSMesa is (before importing ``mujoco``).
"""

from __future__ import annotations

import ctypes.util
import os
import sys


def _pick_headless_gl() -> None:
    if "MUJOCO_GL" in os.environ or "mujoco" in sys.modules:
        return
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    for backend, library in (("egl", "EGL"), ("osmesa", "OSMesa")):
        if ctypes.util.find_library(library):
            os.environ["MUJOCO_GL"] = backend
            return


_pick_headless_gl()
