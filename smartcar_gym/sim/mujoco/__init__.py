"""The MuJoCo engine behind the simulator facade (the ``mujoco`` extra).

``model`` builds the ``MjSpec`` of one robot from its URDF (reusable for batched worlds),
``simulator`` is ``MujocoSimulator`` (the clock, stepping, the world's spec, model and data),
``body`` the ``Body`` handles and the visual-only markers, ``render`` the offscreen camera,
``batch`` N copies of one world stepped in C and ``cars`` the batched vector env's car batch.
``ENGINE`` describes the engine to ``sim.engines``; importing this package does not import
``mujoco`` (making a world does, and says which extra is missing).

Headless rendering: MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when ``mujoco`` is first
imported. Without a display and without ``MUJOCO_GL`` set, this package sets it to ``egl`` if
the EGL library is installed, else to ``osmesa`` if OSMesa is (before importing ``mujoco``).
"""

from __future__ import annotations

import ctypes.util
import os
import sys
from typing import Any

from smartcar_gym.sim.batch import LazyCarBatch
from smartcar_gym.sim.clock import DEFAULT_MAX_SUBSTEP_S, MAX_SUBSTEP_RANGE_S
from smartcar_gym.sim.engines import Engine

EXTRA = 'pip install "smartcar-gym[mujoco]"'


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


def _simulator(**options: Any) -> Any:
    from smartcar_gym.sim.mujoco.simulator import MujocoSimulator

    return MujocoSimulator(**options)


def _window_unavailable() -> str | None:
    try:
        from smartcar_gym.sim.mujoco.window import unavailable
    except ModuleNotFoundError as exc:
        if exc.name != "mujoco":
            raise
        return None  # making the world says which extra is missing
    return unavailable()


ENGINE = Engine(
    name="mujoco",
    simulator=_simulator,
    max_substep_s=DEFAULT_MAX_SUBSTEP_S,
    substep_range_s=MAX_SUBSTEP_RANGE_S,
    window_unavailable=_window_unavailable,
    # measured with 4.0.0 (256 cars): 0.74 MiB resident per car, mostly its MjData arena
    car_batch=LazyCarBatch("smartcar_gym.sim.mujoco.cars:MujocoCars", 800 * 1024),
    batches_differential=False,  # a differential-drive model starts its encoders mid-tick
    module="mujoco",
    extra=EXTRA,
    requirements=("mujoco>=3.10",),
    summary=f"needs the extra: {EXTRA}",
)
