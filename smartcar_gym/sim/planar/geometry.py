"""The navigation task's geometry in the ground plane, as numpy arrays over N cars.

No physics engine: obstacles, laser rays and the car's clearance in 2D, for the planar engine,
one concern per module; this module gathers their public names (``from
smartcar_gym.sim.planar.geometry import cast, clearance, Shapes2D``):

* ``shapes``: ``Shapes2D``, M convex shapes per car (oriented rectangles ``BOX`` and circles
  ``CIRCLE``), e.g. the nav task's obstacles (``Shapes2D.from_layouts``);
* ``raycast``: ``cast``, horizontal rays against them exactly, and ``ray_hits``, the same for
  one world's 3D rays as ``sim.rays.RayHits``;
* ``projection``: a robot's collision shapes placed in base_link's frame and projected onto
  the ground (``outline``), the one projection the model, the clearance (``footprint``) and
  the picture use;
* ``distance``: ``distances`` between shapes and ``clearance``, the smallest distance between
  the car's footprint at its pose and the obstacles, negative (the penetration depth) where
  they overlap.

The 2D model of the 3D world: obstacles are vertical prisms from the ground up to
``OBSTACLE_HEIGHT_M`` (``sim.obstacles.add_obstacle``'s boxes and upright cylinders), the laser's
rays are horizontal at a height within them, and the car stands on the ground (base_link at
z = 0) with its collision shapes below the obstacles' tops. Then a ray hits what its 2D line
hits, and the 3D distance between a car part and an obstacle is the 2D distance between their
projections. How close each is to pybullet and MuJoCo: ``raycast`` and ``distance``.
"""

from __future__ import annotations

from smartcar_gym.sim.planar.distance import BULLET_BOX_MARGIN_M, clearance, distances
from smartcar_gym.sim.planar.projection import AXIS_TOLERANCE, Footprint, footprint
from smartcar_gym.sim.planar.raycast import RayCast, cast, ray_hits
from smartcar_gym.sim.planar.shapes import (
    BOX,
    CIRCLE,
    OBSTACLE_HEIGHT_M,
    OBSTACLE_KINDS,
    Shapes2D,
)

__all__ = [
    "AXIS_TOLERANCE",
    "BOX",
    "BULLET_BOX_MARGIN_M",
    "CIRCLE",
    "OBSTACLE_HEIGHT_M",
    "OBSTACLE_KINDS",
    "Footprint",
    "RayCast",
    "Shapes2D",
    "cast",
    "clearance",
    "distances",
    "footprint",
    "ray_hits",
]
