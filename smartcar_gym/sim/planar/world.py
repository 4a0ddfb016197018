"""What the planar world answers about its obstacles: ray casts and a robot's clearance.

The obstacles (``PlanarSimulator.add_static``: boxes and upright cylinders standing on the
ground) and each robot's footprint (its collision shapes projected onto the ground,
``projection.footprint``, its parts' heights above the ground kept) go through the exact 2D
functions of ``raycast`` and ``distance``: a horizontal ray below the obstacles' tops meets
their outlines, and a car on the ground is as near an obstacle as their outlines are (or, for
a part above the obstacles, by the height between).
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from smartcar_gym.sim.planar.distance import clearance
from smartcar_gym.sim.planar.projection import Footprint, footprint
from smartcar_gym.sim.planar.raycast import ray_hits
from smartcar_gym.sim.planar.shapes import BOX, CIRCLE, OBSTACLE_HEIGHT_M, Shapes2D
from smartcar_gym.sim.rays import RayHits

if TYPE_CHECKING:
    from smartcar_gym.sim.planar.body import PlanarBody, PlanarStatic
    from smartcar_gym.sim.planar.simulator import PlanarSimulator


def obstacle_shapes(statics: list[PlanarStatic]) -> Shapes2D:
    """One world's obstacles (N = 1) as ``Shapes2D``, in the order given."""
    kind = [BOX if s.kind == "box" else CIRCLE for s in statics]
    centre = [s.position[:2] for s in statics]
    yaw = [s.yaw for s in statics]
    half = [s.size[:2] if s.kind == "box" else (s.size[0], s.size[0]) for s in statics]
    if not statics:
        return Shapes2D.from_arrays(np.zeros((1, 0)), np.zeros((1, 0, 2)),
                                             np.zeros((1, 0)), np.zeros((1, 0, 2)))
    return Shapes2D.from_arrays([kind], [centre], [yaw], [half])


def _height(statics: list[PlanarStatic]) -> float:
    """The obstacles' common top (m): their tallest."""
    return max((2.0 * s.size[2] for s in statics), default=OBSTACLE_HEIGHT_M)


def outlines(sim: PlanarSimulator, statics: tuple[PlanarStatic, ...]) -> Shapes2D:
    """``obstacle_shapes`` of ``statics`` (bodies of ``sim``), kept on ``sim`` while they are
    the same bodies (held there, so none is a new one at an old address): a world's scans
    and the batch's ``load`` of it ask again."""
    kept = getattr(sim, "_outlines", None)
    if kept is None or not _same(kept[0], statics):
        kept = (statics, obstacle_shapes(list(statics)))
        sim._outlines = kept
    return kept[1]


def _same(kept: tuple[PlanarStatic, ...], statics: tuple[PlanarStatic, ...]) -> bool:
    return len(kept) == len(statics) and all(a is b for a, b in zip(kept, statics,
                                                                    strict=True))


def cast_world(sim: PlanarSimulator, starts: np.ndarray, ends: np.ndarray) -> RayHits:
    """``cast_rays`` in a planar world: exact 2D casts against the obstacles' outlines; each
    hit reports the obstacle's index among the world's bodies."""
    statics = tuple(s for s in sim.statics() if not s.hidden_from_rays)
    kept = getattr(sim, "_ray_world", None)
    if kept is None or not _same(kept[0], statics):
        # the same static bodies keep their outlines, indices and height from scan to scan
        where = {name: i for i, name in enumerate(sim._bodies)}
        ids = np.array([where[s.name] for s in statics], dtype=int)
        kept = (statics, outlines(sim, statics), ids, _height(list(statics)))
        sim._ray_world = kept
    return ray_hits(starts, ends, kept[1], kept[2], height=kept[3])


def footprint_of(body: PlanarBody) -> Footprint:
    """A robot's footprint with its parts' heights above the ground (kept on the body)."""
    found = getattr(body, "_footprint", None)
    if found is None:
        local = footprint(body.tables.robot)
        found = dataclasses.replace(local, z_range=local.z_range + body.height)
        body._footprint = found
    return found


def body_distance(sim: PlanarSimulator, body: PlanarBody, other: Any,
                  max_distance_m: float) -> float:
    """The smallest distance (m) between a robot and a static body (< 0: overlapping), at
    most ``max_distance_m``; ``max_distance_m`` for anything that is not an obstacle."""
    if getattr(other, "kind", None) not in ("box", "cylinder") or not other.collides:
        return float(max_distance_m)
    (x, y, _), q = body.link_pose()
    qx, qy, qz, qw = q  # pose_from's yaw, as the batch computes it
    pose = np.array([[x, y, math.atan2(2.0 * (qw * qz + qx * qy),
                                       1.0 - 2.0 * (qy * qy + qz * qz))]])
    return float(clearance(footprint_of(body), pose, obstacle_shapes([other]),
                                    max_distance_m, height=_height([other]))[0])
