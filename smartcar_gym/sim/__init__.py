"""The simulator facade: the only package that imports pybullet or mujoco.

Each engine is a folder of its own: ``pybullet`` (the default), ``mujoco`` (the ``mujoco``
extra) and ``planar``; ``engines`` is the registry of their descriptions and
``engines.make_simulator(engine)`` makes a world of one. ``contracts`` says what every engine's
simulator and bodies offer, ``clock.EventClock`` is the clock every engine shares, and
``markers``, ``obstacles``, ``rays`` and ``dynamics`` work on any engine's world.
Importing this package imports no physics library.
"""

from __future__ import annotations
