"""The simulator facade: the only package that imports pybullet or mujoco.

Each engine is a folder of its own: ``pybullet`` (the default), ``mujoco`` (the ``mujoco``
extra) and ``planar``; ``engines`` is the registry of their descriptions and
``engines.make_simulator(engine)`` makes a world of one. ``contracts`` says what every engine's
simulator and bodies offer, ``clock.EventClock`` is the clock every engine shares, and
``markers``, ``obstacles``, ``rays`` and ``dynamics`` work on any engine's world.

``Simulator`` and ``Body`` here are pybullet's (``sim.pybullet``), as they always were; they are
imported when first asked for, so that importing this package imports no physics library.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Body", "EventSource", "Simulator"]


def __getattr__(name: str) -> Any:
    if name == "Body":
        from smartcar_gym.sim.pybullet.body import Body

        return Body
    if name == "Simulator":
        from smartcar_gym.sim.pybullet.simulator import Simulator

        return Simulator
    if name == "EventSource":
        from smartcar_gym.sim.clock import EventSource

        return EventSource
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
