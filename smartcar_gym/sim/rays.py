"""Ray casts: many rays in one ``rayTestBatch`` call, and bodies the rays pass through.

A range sensor on a robot must not see the robot itself. ``hide_from_rays`` moves every link of
a body into a collision filter group that ``cast_rays`` leaves out of its mask; the body still
collides with everything it collided with before (the ground and static bodies keep masks that
include every group but their own).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smartcar_gym.sim.body import Body
from smartcar_gym.sim.bullet import pybullet
from smartcar_gym.sim.clock import EventClock

#: the collision filter group of bodies hidden from rays (bit 10: unused by Bullet's own groups)
HIDDEN_GROUP = 1 << 10
ALL_GROUPS = -1
#: the most rays one ``rayTestBatch`` call takes
MAX_RAYS = int(pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE)


@dataclass(frozen=True)
class RayHits:
    """What each of N rays hit first: ``fraction`` of the way from start to end (1 where it
    hit nothing), the body's pybullet id (-1: nothing) and the hit point in the world (m)."""

    fraction: np.ndarray  # (N,)
    body: np.ndarray  # (N,) int
    point: np.ndarray  # (N, 3)

    @property
    def hit(self) -> np.ndarray:
        """True where the ray hit something."""
        return self.body >= 0


def hide_from_rays(body: Body) -> None:
    """Let ``cast_rays`` pass through every link of ``body``; its collisions are unchanged."""
    body.hide_from_rays()


def cast_rays(sim: EventClock, starts: np.ndarray, ends: np.ndarray) -> RayHits:
    """Cast rays from ``starts`` to ``ends`` (``(N, 3)``, world frame, m) in one batch.

    Bodies passed to ``hide_from_rays`` are not hit. A ray that starts inside a convex shape
    does not hit that shape (Bullet's rule). Single-threaded, so results are reproducible.
    """
    starts = np.asarray(starts, dtype=float)
    ends = np.asarray(ends, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != 3 or starts.shape != ends.shape:
        raise ValueError(f"ray starts and ends must be two (N, 3) arrays, got shapes "
                         f"{starts.shape} and {ends.shape}")
    if not 1 <= len(starts) <= MAX_RAYS:
        raise ValueError(f"one batch casts 1 to {MAX_RAYS} rays (pybullet's limit), "
                         f"got {len(starts)}")
    return sim.ray_batch(starts, ends)


def bullet_rays(client, starts: np.ndarray, ends: np.ndarray) -> RayHits:
    """pybullet's ``rayTestBatch`` of checked rays, single-threaded, hidden bodies left out."""
    results = client.rayTestBatch(starts, ends, numThreads=1,
                                  collisionFilterMask=ALL_GROUPS ^ HIDDEN_GROUP)
    body, _, fraction, point, _ = zip(*results, strict=True)
    return RayHits(fraction=np.array(fraction, dtype=float), body=np.array(body, dtype=int),
                   point=np.array(point, dtype=float))
