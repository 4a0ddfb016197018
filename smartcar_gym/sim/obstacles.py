"""Static obstacles: boxes and upright cylinders that stand on the ground and collide.

``add_obstacle`` creates one fixed body (the engine never moves it) with a collision shape and a
visual of the same shape. ``nearest_distance`` measures how close a body is to some others
(<= 0: touching), from the bodies' current poses: it works whether or not the physics was
stepped since they last moved (a kinematically moved robot, ``controller_mode="sim"``, gets no
contact points from the engine).
"""

from __future__ import annotations

from collections.abc import Sequence

from smartcar_gym.sim.contracts import Body, Simulator

SHAPES = ("box", "cylinder")
OBSTACLE_COLOR = (0.55, 0.55, 0.6, 1.0)


def add_obstacle(
    sim: Simulator,
    name: str,
    shape: str,
    size: Sequence[float],
    position: Sequence[float],
    yaw: float = 0.0,
    height: float = 0.3,
    rgba: Sequence[float] = OBSTACLE_COLOR,
    pillar: bool = False,
) -> Body:
    """A static obstacle standing on the ground, centred on ``position`` (x, y), turned by ``yaw``.

    ``size`` is (length along x, width along y) of a box before the turn, or (diameter,) of a
    cylinder; ``height`` in m; ``pillar``: a cylinder whose top nothing reaches (the engine
    may round its ends: ``Simulator.add_static``). Returns its ``Body`` handle (also
    ``sim.body(name)``).
    """
    if shape not in SHAPES:
        raise ValueError(f"obstacle shape must be one of {SHAPES}, got {shape!r}")
    if sim.has_body(name):
        raise ValueError(f"a body named {name!r} already exists")
    if shape == "box":
        half = (size[0] / 2.0, size[1] / 2.0, height / 2.0)
    else:
        half = (size[0] / 2.0, size[0] / 2.0, height / 2.0)
    extra = {"pillar": True} if pillar and shape == "cylinder" else {}
    return sim.add_static(name, shape, half, (float(position[0]), float(position[1]),
                                              height / 2.0), yaw, rgba, **extra)


def nearest_distance(body: Body, others: Sequence[Body], max_distance_m: float) -> float:
    """The smallest distance (m) between ``body``'s collision shapes and those of ``others``
    at their current poses (< 0: overlapping), or ``max_distance_m`` if none is nearer."""
    nearest = max_distance_m
    for other in others:
        nearest = min(nearest, body.distance_to(other, max_distance_m))
    return float(nearest)
