"""Static obstacles: boxes and upright cylinders that stand on the ground and collide.

``add_obstacle`` creates one fixed body (mass 0: pybullet never moves it) with a collision shape
and a visual of the same shape. ``nearest_distance`` measures how close a body is to some others
(<= 0: touching), from the bodies' current poses: it works whether or not the physics was
stepped since they last moved (a kinematically moved robot, ``controller_mode="sim"``, gets no
contact points from pybullet).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from smartcar_gym.sim.body import Body
from smartcar_gym.sim.bullet import pybullet
from smartcar_gym.sim.simulator import Simulator

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
) -> Body:
    """A static obstacle standing on the ground, centred on ``position`` (x, y), turned by ``yaw``.

    ``size`` is (length along x, width along y) of a box before the turn, or (diameter,) of a
    cylinder; ``height`` in m. Returns its ``Body`` handle (also ``sim.body(name)``).
    """
    if shape not in SHAPES:
        raise ValueError(f"obstacle shape must be one of {SHAPES}, got {shape!r}")
    if sim.has_body(name):
        raise ValueError(f"a body named {name!r} already exists")
    c = sim.client
    if shape == "box":
        half = [size[0] / 2.0, size[1] / 2.0, height / 2.0]
        collision = c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half)
        visual = c.createVisualShape(pybullet.GEOM_BOX, halfExtents=half, rgbaColor=list(rgba))
    else:
        radius = size[0] / 2.0
        collision = c.createCollisionShape(pybullet.GEOM_CYLINDER, radius=radius, height=height)
        visual = c.createVisualShape(pybullet.GEOM_CYLINDER, radius=radius, length=height,
                                     rgbaColor=list(rgba))
    uid = c.createMultiBody(
        baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual,
        basePosition=[float(position[0]), float(position[1]), height / 2.0],
        baseOrientation=[0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)],
    )
    body = Body(sim, name, uid)
    sim._bodies[name] = body  # the simulator's registry of names (cleared by its reset)
    return body


def nearest_distance(body: Body, others: Sequence[Body], max_distance_m: float) -> float:
    """The smallest distance (m) between ``body``'s collision shapes and those of ``others``
    at their current poses (< 0: overlapping), or ``max_distance_m`` if none is nearer."""
    closest = body.sim.client.getClosestPoints
    nearest = max_distance_m
    for other in others:
        for point in closest(body.uid, other.uid, max_distance_m):
            nearest = min(nearest, point[8])
    return float(nearest)
